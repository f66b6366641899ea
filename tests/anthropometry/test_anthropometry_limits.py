"""Tests of the anthropometric limits table (toolkit.anthropometry.limits)."""

import math
import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.anthropometry import limits as L
from toolkit.errors import InputError
from toolkit.skeleton import SKELETON_14

REPO = Path(__file__).resolve().parents[2]
#: Percentiles are stored in code to 0.01 mm, so a recomputation agrees to half of that.
PERCENTILE_TOL_MM = 0.005


def realdata_dir() -> Path:
    return Path(os.environ.get("TOOLKIT_REALDATA", REPO.parent / "shared" / "realdata"))


def _pairs(limits):
    return [frozenset((lim.joint_a, lim.joint_b)) for lim in limits]


def test_every_bone_has_exactly_one_limit():
    pairs = _pairs(L.LIMITS_14)
    for a, b in SKELETON_14.bones:
        key = frozenset((SKELETON_14.joint_names[a], SKELETON_14.joint_names[b]))
        assert pairs.count(key) == 1, key
    assert len(set(pairs)) == len(pairs)


@pytest.mark.parametrize("a, b, max_only", [
    ("l_shoulder", "r_shoulder", False), ("l_hip", "r_hip", False),
    ("head", "l_hip", False), ("head", "r_hip", False),
    ("l_shoulder", "r_hip", False), ("r_shoulder", "l_hip", False),
    ("l_shoulder", "l_hip", False), ("r_shoulder", "r_hip", False),
    ("l_shoulder", "l_wrist", True), ("r_shoulder", "r_wrist", True),
    ("l_hip", "l_ankle", True), ("r_hip", "r_ankle", True),
    ("head", "l_ankle", True), ("head", "r_ankle", True),
])
def test_required_distances_present(a, b, max_only):
    lim = [x for x in L.LIMITS_14 if frozenset((x.joint_a, x.joint_b)) == frozenset((a, b))]
    assert len(lim) == 1
    assert (lim[0].min_m == 0.0) == max_only
    assert lim[0].max_m > 0


def test_limits_are_rounded_centimetres_and_ordered():
    for lim in L.LIMITS_14:
        assert 0 <= lim.min_m < lim.max_m, lim
        for v in (lim.min_m, lim.max_m):
            assert abs(v * 100 - round(v * 100)) < 1e-9, lim
        assert lim.source


def test_left_and_right_limits_match():
    by_pair = {(lim.joint_a, lim.joint_b): lim for lim in L.LIMITS_14}
    flip = SKELETON_14.flip_permutation
    names = SKELETON_14.joint_names
    for (a, b), lim in by_pair.items():
        ma, mb = names[flip[names.index(a)]], names[flip[names.index(b)]]
        mirror = by_pair.get((ma, mb)) or by_pair.get((mb, ma))
        assert mirror is not None, (a, b)
        assert (mirror.min_m, mirror.max_m) == (lim.min_m, lim.max_m)


def test_widening_and_rounding_by_hand():
    # 10 % of 400 mm is 40 mm (> 20 mm); 10 % of 100 mm is 10 mm, so the 20 mm floor applies
    assert L.widen_down_mm(400.0) == pytest.approx(360.0)
    assert L.widen_up_mm(400.0) == pytest.approx(440.0)
    assert L.widen_down_mm(100.0) == pytest.approx(80.0)
    assert L.widen_up_mm(100.0) == pytest.approx(120.0)
    assert L.round_down_m(254.925) == 0.25
    assert L.round_up_m(401.5) == 0.41
    assert L.round_up_m(410.0) == 0.41      # exact values are not bumped by float error
    assert L.round_down_m(300.0) == 0.30


def test_upper_arm_and_hip_width_by_hand():
    arm = next(x for x in L.LIMITS_14 if x.joint_a == "l_shoulder" and x.joint_b == "l_elbow")
    # female p5 283.25 - 28.325 = 254.9 mm -> 0.25 m; male p95 365 + 36.5 = 401.5 mm -> 0.41 m
    assert (arm.min_m, arm.max_m) == (0.25, 0.41)
    hips = next(x for x in L.LIMITS_14 if x.joint_a == "l_hip" and x.joint_b == "r_hip")
    # 0.60 * bicristal female p5: 142.2 - 20 = 122.2 -> 0.12
    # 0.72 * bicristal male p95: 219.6 + 22 = 241.6 -> 0.25
    assert (hips.min_m, hips.max_m) == (0.12, 0.25)
    shoulders = next(x for x in L.LIMITS_14
                     if x.joint_a == "l_shoulder" and x.joint_b == "r_shoulder")
    # (335 - 50 glenohumeral) - 28.5 = 256.5 -> 0.25; 447 + 44.7 = 491.7 -> 0.50
    assert (shoulders.min_m, shoulders.max_m) == (0.25, 0.50)


def test_torso_diagonal_from_vertical_and_hip_ranges():
    torso = next(x for x in L.LIMITS_14 if x.joint_a == "neck" and x.joint_b == "l_hip")
    v_lo, v_hi = L.widen_down_mm(443.0), L.widen_up_mm(667.0)
    h_lo, h_hi = L.widen_down_mm(142.2) / 2, L.widen_up_mm(219.6) / 2
    assert torso.min_m == math.floor(math.hypot(v_lo, h_lo) / 10) / 100
    assert torso.max_m == math.ceil(math.hypot(v_hi, h_hi) / 10) / 100


def test_ankle_clearance():
    # lateral malleolus height, female p5 54 mm - 20 mm = 34 mm -> 0.03 m
    assert L.ANKLE_CLEARANCE_M == 0.03


def test_build_limits_needs_every_expression():
    pct = dict(L.ANSUR_II_PERCENTILES)
    del pct[L.UPPER_ARM]
    with pytest.raises(InputError, match="acromionradialelength"):
        L.build_limits(pct)


def test_evaluate_expression():
    cols = {"a": np.array([3.0, 6.0]), "b": np.array([4.0, 8.0])}
    np.testing.assert_allclose(L.evaluate_expression("hypot(a, b)", cols), [5.0, 10.0])
    np.testing.assert_allclose(L.evaluate_expression("a + b / 2 - -1", cols), [6.0, 11.0])
    np.testing.assert_allclose(L.evaluate_expression("0.5 * a", cols), [1.5, 3.0])
    assert L.expression_columns("hypot(a, b) - c") == {"a", "b", "c"}
    with pytest.raises(InputError, match="column"):
        L.evaluate_expression("a + missing", cols)
    with pytest.raises(InputError):
        L.evaluate_expression("__import__('os')", cols)
    with pytest.raises(InputError):
        L.evaluate_expression("a ** 2", cols)


def _write_survey(path: Path, n: int, rng: np.random.Generator, scale: float) -> dict:
    cols = sorted(set().union(*(L.expression_columns(e) for e in L.ANSUR_II_PERCENTILES)))
    base = {"stature": 1700, "tragiontopofhead": 130, "cervicaleheight": 1450,
            "acromialheight": 1400,
            "biacromialbreadth": 390, "acromionradialelength": 320, "radialestylionlength": 250,
            "trochanterionheight": 880, "lateralfemoralepicondyleheight": 480,
            "lateralmalleolusheight": 70, "bicristalbreadth": 270}
    values = {c: np.round(base[c] * scale * rng.uniform(0.9, 1.1, n)) for c in cols}
    with open(path, "w") as f:
        # header case as in the female file ("SubjectId"), plus a text column
        f.write("SubjectId,Gender," + ",".join(c.capitalize() if c == "stature" else c
                                               for c in cols) + "\n")
        f.writelines(f"{i},x," + ",".join(f"{values[c][i]:.0f}" for c in cols) + "\n"
                     for i in range(n))
    return values


def test_derive_limits_from_small_survey(tmp_path):
    rng = np.random.default_rng(3)
    male = _write_survey(tmp_path / "m.csv", 40, rng, 1.05)
    female = _write_survey(tmp_path / "f.csv", 30, rng, 0.95)
    d = L.derive_limits_from_ansur(tmp_path / "m.csv", tmp_path / "f.csv")
    assert (d.n_male, d.n_female) == (40, 30)
    p5 = np.percentile(female["stature"] - female["tragiontopofhead"]
                       - female["cervicaleheight"], 5)
    p95 = np.percentile(male["stature"] - male["tragiontopofhead"] - male["cervicaleheight"], 95)
    got = d.percentiles[L.HEAD_OVER_C7]
    assert got.female_p5_mm == pytest.approx(p5) and got.male_p95_mm == pytest.approx(p95)
    p95 = np.percentile(np.hypot(male["biacromialbreadth"] / 2,
                                 male["cervicaleheight"] - male["acromialheight"]), 95)
    assert d.percentiles[L.NECK_C7_TO_ACROMION].male_p95_mm == pytest.approx(p95)
    assert d.limits == L.build_limits(d.percentiles)


def test_derive_limits_reports_bad_files(tmp_path):
    rng = np.random.default_rng(0)
    _write_survey(tmp_path / "ok.csv", 5, rng, 1.0)
    (tmp_path / "nocol.csv").write_text("subjectid,stature\n1,1700\n")
    with pytest.raises(InputError, match="nocol.csv: header"):
        L.derive_limits_from_ansur(tmp_path / "ok.csv", tmp_path / "nocol.csv")
    text = (tmp_path / "ok.csv").read_text().splitlines()
    text[3] = text[3].replace(",", ",abc", 3)
    (tmp_path / "bad.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(InputError, match="bad.csv: line 4"):
        L.derive_limits_from_ansur(tmp_path / "bad.csv", tmp_path / "ok.csv")
    with pytest.raises(InputError, match="missing.csv"):
        L.derive_limits_from_ansur(tmp_path / "missing.csv", tmp_path / "ok.csv")


@pytest.mark.realdata
def test_in_code_table_matches_ansur_ii_csvs():
    folder = realdata_dir() / "ansur2"
    male, female = folder / "ANSUR_II_MALE_Public.csv", folder / "ANSUR_II_FEMALE_Public.csv"
    if not (male.exists() and female.exists()):
        pytest.skip(f"ANSUR II CSVs not found in {folder}")
    d = L.derive_limits_from_ansur(male, female)
    assert (d.n_male, d.n_female) == (4082, 1986)
    assert set(d.percentiles) == set(L.ANSUR_II_PERCENTILES)
    for expr, p in d.percentiles.items():
        q = L.ANSUR_II_PERCENTILES[expr]
        assert p.female_p5_mm == pytest.approx(q.female_p5_mm, abs=PERCENTILE_TOL_MM), expr
        assert p.male_p95_mm == pytest.approx(q.male_p95_mm, abs=PERCENTILE_TOL_MM), expr
    assert d.limits == L.LIMITS_14
    assert d.ankle_clearance_m == L.ANKLE_CLEARANCE_M


def test_markdown_table_is_in_the_docs():
    table = L.limits_markdown()
    lines = table.splitlines()
    merged = {(x.name, x.min_m, x.max_m) for x in L.LIMITS_14}
    assert len(lines) == 2 + len(merged)
    doc = (REPO / "docs" / "anthropometry.md").read_text()
    assert L.limit_tables_markdown() in doc, \
        "docs/anthropometry.md is out of date: paste limit_tables_markdown()"
