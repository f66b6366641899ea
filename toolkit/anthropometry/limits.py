"""Anthropometric limits: minimum and maximum joint distances of the 14-joint skeleton.

Source 000 (§3.2) rejects a joint position when a bone length or a distance
between unconnected joints leaves the anthropometric standards, taking "the
5th-percentile female rounded down as minimum and the 95th-percentile male
rounded up as maximum" from the NASA Man-Systems Integration Standards
(NASA-STD-3000, Vol. I §3, cited as [NAS09]).  The MSIS segment tables could
not be read (only the introduction of that section is available), so the
percentiles here come from the ANSUR II survey (US Army, 2012; Gordon et al.
2014, NATICK/TR-15/007), with the same rule:

``min_m = floor_cm(widen_down(female p5))`` and ``max_m = ceil_cm(widen_up(male p95))``

ANSUR II measures surface landmarks (acromion, trochanterion, lateral femoral
epicondyle, ...), not joint centres, and a standing posture.  Every percentile is
therefore widened by :data:`LANDMARK_WIDENING_FRACTION` of its value or
:data:`LANDMARK_WIDENING_MIN_M`, whichever is larger, before rounding; the
shoulder joint centres (glenohumeral) also lie :data:`GLENOHUMERAL_INSET_M`
medial of the acromion.  Distances that are not straight segments (the
neck-hip bone, head-hip, shoulder-hip) combine a vertical and a horizontal
range with ``hypot`` (see :func:`build_limits`).

The table lives here, in code: :data:`ANSUR_II_PERCENTILES` holds the survey
figures and :data:`LIMITS_14` the widened, rounded limits built from them.
:func:`derive_limits_from_ansur` recomputes both from the survey's CSV files.
:func:`limit_tables_markdown` prints the tables of ``docs/anthropometry.md``.
"""

from __future__ import annotations

import ast
import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolkit.errors import InputError

#: Relative widening of every survey percentile (surface landmarks vs joint centres,
#: ANSUR II's Army population vs the MSIS range, reconstruction noise).
LANDMARK_WIDENING_FRACTION = 0.10
#: Smallest widening in metres (the acromion lies 3-5 cm from the shoulder centre,
#: the femoral epicondyle 1-3 cm from the knee line); used where 10 % is less.
LANDMARK_WIDENING_MIN_M = 0.020
#: Horizontal distance from the acromion (surface) to the glenohumeral joint centre, metres.
GLENOHUMERAL_INSET_M = 0.025
#: Hip joint centres are 0.36 inter-ASIS widths from the midline (Bell et al. 1990); ANSUR II
#: has bicristal breadth only, which is wider, so 2 x 0.36 of it is an upper estimate.
HIP_CENTRE_FACTOR_UPPER = 0.72
#: Assumed lower estimate of hip-centre distance / bicristal breadth (no source; see README).
HIP_CENTRE_FACTOR_LOWER = 0.60
#: Percentiles of the source document (000 §3.2): female p5 for minima, male p95 for maxima.
MIN_PERCENTILE = 5.0
MAX_PERCENTILE = 95.0
#: Rounding step of the limits (centimetres, as in source 000: "rounded down / up").
ROUNDING_STEP_M = 0.01

# ANSUR II expressions (columns in mm, evaluated per subject before taking percentiles).
HEAD_OVER_C7 = "stature - tragiontopofhead - cervicaleheight"
HEAD_OVER_ACROMION = "stature - tragiontopofhead - acromialheight"
HALF_BIACROMIAL = "biacromialbreadth / 2"
NECK_C7_TO_ACROMION = "hypot(biacromialbreadth / 2, cervicaleheight - acromialheight)"
UPPER_ARM = "acromionradialelength"
FOREARM = "radialestylionlength"
ACROMION_OVER_HIP = "acromialheight - trochanterionheight"
C7_OVER_HIP = "cervicaleheight - trochanterionheight"
THIGH = "trochanterionheight - lateralfemoralepicondyleheight"
SHANK = "lateralfemoralepicondyleheight - lateralmalleolusheight"
BIACROMIAL = "biacromialbreadth"
HIP_WIDTH_LOWER = f"{HIP_CENTRE_FACTOR_LOWER:.2f} * bicristalbreadth"
HIP_WIDTH_UPPER = f"{HIP_CENTRE_FACTOR_UPPER:.2f} * bicristalbreadth"
HEAD_OVER_HIP = "stature - tragiontopofhead - trochanterionheight"
LEG = "trochanterionheight - lateralmalleolusheight"
ARM = "acromionradialelength + radialestylionlength"
HEAD_OVER_ANKLE = "stature - tragiontopofhead - lateralmalleolusheight"
ANKLE_HEIGHT = "lateralmalleolusheight"


@dataclass(frozen=True)
class SurveyPercentiles:
    """Percentiles of one ANSUR II expression over the survey's subjects.

    Attributes
    ----------
    expression : str
        Arithmetic of ANSUR II column names (mm), e.g. ``"stature - cervicaleheight"``.
    female_p5_mm : float
        5th percentile over the female subjects, mm.
    male_p95_mm : float
        95th percentile over the male subjects, mm.
    """

    expression: str
    female_p5_mm: float
    male_p95_mm: float


def _p(expression: str, female_p5_mm: float, male_p95_mm: float) -> tuple[str, SurveyPercentiles]:
    return expression, SurveyPercentiles(expression, female_p5_mm, male_p95_mm)


#: ANSUR II 2012 figures (public release: 4082 male, 1986 female subjects), mm to 0.01, numpy's
#: linear-interpolation percentiles of the per-subject values.  Recomputed and checked by
#: ``tests/anthropometry/test_limits.py`` when the survey CSVs are present.
ANSUR_II_PERCENTILES: dict[str, SurveyPercentiles] = dict([
    _p(HEAD_OVER_C7, 87.0, 129.0),
    _p(HEAD_OVER_ACROMION, 143.0, 213.0),
    _p(HALF_BIACROMIAL, 167.5, 223.5),
    _p(NECK_C7_TO_ACROMION, 175.39, 240.16),
    _p(UPPER_ARM, 283.25, 365.0),
    _p(FOREARM, 218.0, 295.0),
    _p(ACROMION_OVER_HIP, 443.0, 593.0),
    _p(C7_OVER_HIP, 503.0, 667.0),
    _p(THIGH, 340.0, 458.0),
    _p(SHANK, 361.0, 460.0),
    _p(BIACROMIAL, 335.0, 447.0),
    _p(HIP_WIDTH_LOWER, 142.2, 183.0),
    _p(HIP_WIDTH_UPPER, 170.64, 219.6),
    _p(HEAD_OVER_HIP, 603.0, 784.0),
    _p(LEG, 716.0, 910.0),
    _p(ARM, 507.0, 655.0),
    _p(HEAD_OVER_ANKLE, 1342.0, 1660.0),
    _p(ANKLE_HEIGHT, 54.0, 83.0),
])


@dataclass(frozen=True)
class Limit:
    """Allowed range of the distance between two joints.

    Attributes
    ----------
    name : str
        What is measured (``"upper arm"``, ``"shoulder - opposite hip"``).
    joint_a, joint_b : str
        Joint names of :data:`toolkit.skeleton.SKELETON_14`.
    min_m, max_m : float
        Allowed distance range, metres (``min_m = 0`` for "maximum only" rows).
    source : str
        How the range was derived: the ANSUR II expressions, their percentiles and
        the widened values, mm.
    """

    name: str
    joint_a: str
    joint_b: str
    min_m: float
    max_m: float
    source: str


# --------------------------------------------------------------------- rules
def widen_down_mm(value_mm: float) -> float:
    """Lower a percentile by the landmark widening (10 % or 20 mm, whichever is larger)."""
    return value_mm - max(LANDMARK_WIDENING_FRACTION * value_mm, 1000.0 * LANDMARK_WIDENING_MIN_M)


def widen_up_mm(value_mm: float) -> float:
    """Raise a percentile by the landmark widening (10 % or 20 mm, whichever is larger)."""
    return value_mm + max(LANDMARK_WIDENING_FRACTION * value_mm, 1000.0 * LANDMARK_WIDENING_MIN_M)


def round_down_m(value_mm: float) -> float:
    """Millimetres to metres, rounded down to :data:`ROUNDING_STEP_M`."""
    steps = math.floor(value_mm / (1000.0 * ROUNDING_STEP_M) + 1e-9)
    return round(steps * ROUNDING_STEP_M, 6)


def round_up_m(value_mm: float) -> float:
    """Millimetres to metres, rounded up to :data:`ROUNDING_STEP_M`."""
    steps = math.ceil(value_mm / (1000.0 * ROUNDING_STEP_M) - 1e-9)
    return round(steps * ROUNDING_STEP_M, 6)


@dataclass(frozen=True)
class _Range:
    """A widened range in mm with the text that explains each end."""

    lo: float
    hi: float
    lo_text: str
    hi_text: str


def _survey_range(pct: dict[str, SurveyPercentiles], lo_expr: str | None, hi_expr: str,
                  lo_offset_mm: float = 0.0, offset_text: str = "") -> _Range:
    hi_raw = _get(pct, hi_expr).male_p95_mm
    hi = widen_up_mm(hi_raw)
    hi_text = f"male p95 of `{hi_expr}` = {hi_raw:.1f}, widened {hi:.1f}"
    if lo_expr is None:
        return _Range(0.0, hi, "none (maximum only)", hi_text)
    lo_raw = _get(pct, lo_expr).female_p5_mm + lo_offset_mm
    lo = widen_down_mm(lo_raw)
    lo_text = f"female p5 of `{lo_expr}`{offset_text} = {lo_raw:.1f}, widened {lo:.1f}"
    return _Range(lo, hi, lo_text, hi_text)


def _get(pct: dict[str, SurveyPercentiles], expr: str) -> SurveyPercentiles:
    try:
        return pct[expr]
    except KeyError:
        raise InputError("percentiles", f"an entry for the ANSUR II expression {expr!r}",
                         f"only {sorted(pct)}") from None


def _diagonal(vertical: _Range, horizontal: _Range, h_name: str) -> _Range:
    """hypot of a vertical and a horizontal range, end by end (conservative)."""
    lo = math.hypot(vertical.lo, horizontal.lo)
    hi = math.hypot(vertical.hi, horizontal.hi)
    return _Range(lo, hi,
                  f"hypot(vertical {vertical.lo:.1f}, {h_name} {horizontal.lo:.1f}) = {lo:.1f}",
                  f"hypot(vertical {vertical.hi:.1f}, {h_name} {horizontal.hi:.1f}) = {hi:.1f}")


def _limit(name: str, a: str, b: str, r: _Range, note: str = "") -> Limit:
    src = f"min: {r.lo_text}; max: {r.hi_text} (mm)"
    if note:
        src += f". {note}"
    lo = round_down_m(r.lo) if r.lo > 0 else 0.0
    return Limit(name, a, b, lo, round_up_m(r.hi), src)


def _both_sides(name: str, a: str, b: str, r: _Range, note: str = "") -> list[Limit]:
    """The limit for the left side and its mirror (``l_`` <-> ``r_``)."""
    def mirror(j: str) -> str:
        return "r_" + j[2:] if j.startswith("l_") else "l_" + j[2:] if j.startswith("r_") else j
    return [_limit(name, a, b, r, note), _limit(name, mirror(a), mirror(b), r, note)]


def build_limits(percentiles: dict[str, SurveyPercentiles] | None = None) -> tuple[Limit, ...]:
    """Limits of :data:`~toolkit.skeleton.SKELETON_14` from survey percentiles.

    Parameters
    ----------
    percentiles : dict of str to SurveyPercentiles, optional
        Keyed by ANSUR II expression; default :data:`ANSUR_II_PERCENTILES`.

    Returns
    -------
    tuple of Limit
        The 13 bones first (in the skeleton's bone order), then distances
        between unconnected joints.

    Notes
    -----
    Joint conventions: ``neck`` lies between the shoulders somewhere from C7
    (cervicale) height down to shoulder (acromion) height, so ranges that
    involve the neck take the shorter convention for the minimum and the
    longer for the maximum; ``head`` is the head centre at tragion level;
    shoulders and hips are joint centres.  Diagonal distances are
    ``hypot(vertical, horizontal)`` of two widened ranges, lower ends together
    and upper ends together.
    """
    pct = ANSUR_II_PERCENTILES if percentiles is None else percentiles
    gh = 1000.0 * GLENOHUMERAL_INSET_M
    gh_note = f", minus {gh:.0f} glenohumeral inset"
    hip_width = _survey_range(pct, HIP_WIDTH_LOWER, HIP_WIDTH_UPPER)
    half_hip = _Range(hip_width.lo / 2, hip_width.hi / 2, "", "")
    shoulder_width = _survey_range(pct, BIACROMIAL, BIACROMIAL, -2 * gh,
                                   f", minus 2 x {gh:.0f} glenohumeral inset")
    torso = _survey_range(pct, ACROMION_OVER_HIP, C7_OVER_HIP)
    shoulder_over_hip = _survey_range(pct, ACROMION_OVER_HIP, ACROMION_OVER_HIP)
    head_over_hip = _survey_range(pct, HEAD_OVER_HIP, HEAD_OVER_HIP)
    cross = _Range((shoulder_width.lo + hip_width.lo) / 2,
                   (shoulder_width.hi + hip_width.hi) / 2, "", "")
    same = _Range(max(0.0, (shoulder_width.lo - hip_width.hi) / 2),
                  max(0.0, (shoulder_width.hi - hip_width.lo) / 2), "", "")

    widths_note = (f"Vertical `{ACROMION_OVER_HIP}` widened; widths as for shoulder - shoulder "
                   "and hip - hip")
    bones = [
        _limit("head (neck - head centre)", "neck", "head",
               _survey_range(pct, HEAD_OVER_C7, HEAD_OVER_ACROMION),
               "Minimum with the neck at C7, maximum with the neck at shoulder level"),
        *_both_sides("neck - shoulder", "neck", "l_shoulder",
                     _survey_range(pct, HALF_BIACROMIAL, NECK_C7_TO_ACROMION, -gh, gh_note),
                     "Minimum with the neck at shoulder level, maximum with the neck at C7"),
        *_both_sides("upper arm", "l_shoulder", "l_elbow",
                     _survey_range(pct, UPPER_ARM, UPPER_ARM)),
        *_both_sides("forearm", "l_elbow", "l_wrist", _survey_range(pct, FOREARM, FOREARM)),
        *_both_sides("torso (neck - hip)", "neck", "l_hip",
                     _diagonal(torso, half_hip, "half hip width"),
                     f"Vertical: female p5 of `{ACROMION_OVER_HIP}` (neck at shoulder level) "
                     f"to male p95 of `{C7_OVER_HIP}` (neck at C7), widened; half hip width "
                     f"from `{HIP_WIDTH_LOWER}` and `{HIP_WIDTH_UPPER}`, widened, halved"),
        *_both_sides("thigh", "l_hip", "l_knee", _survey_range(pct, THIGH, THIGH)),
        *_both_sides("shank", "l_knee", "l_ankle", _survey_range(pct, SHANK, SHANK)),
    ]
    distances = [
        _limit("shoulder - shoulder", "l_shoulder", "r_shoulder", shoulder_width),
        _limit("hip - hip", "l_hip", "r_hip", hip_width,
               "Hip joint centres from the iliac-crest breadth "
               "(Bell et al. 1990 factor as upper estimate)"),
        *_both_sides("head - hip", "head", "l_hip",
                     _diagonal(head_over_hip, half_hip, "half hip width"),
                     f"Vertical `{HEAD_OVER_HIP}` widened; half hip width as for hip - hip"),
        *_both_sides("shoulder - opposite hip", "l_shoulder", "r_hip",
                     _diagonal(shoulder_over_hip, cross, "(shoulder width + hip width) / 2"),
                     widths_note),
        *_both_sides("shoulder - hip, same side", "l_shoulder", "l_hip",
                     _diagonal(shoulder_over_hip, same, "(shoulder width - hip width) / 2"),
                     widths_note),
        *_both_sides("shoulder - wrist (arm straight)", "l_shoulder", "l_wrist",
                     _survey_range(pct, None, ARM)),
        *_both_sides("hip - ankle (leg straight)", "l_hip", "l_ankle",
                     _survey_range(pct, None, LEG)),
        *_both_sides("head - ankle (standing)", "head", "l_ankle",
                     _survey_range(pct, None, HEAD_OVER_ANKLE)),
    ]
    return tuple(bones + distances)


def build_ankle_clearance(percentiles: dict[str, SurveyPercentiles] | None = None) -> float:
    """Lowest height of an ankle joint centre above the floor, metres.

    The female p5 of ``lateralmalleolusheight`` (the ankle's bony landmark
    with the foot flat on the floor), widened and rounded down.
    """
    pct = ANSUR_II_PERCENTILES if percentiles is None else percentiles
    return round_down_m(widen_down_mm(_get(pct, ANKLE_HEIGHT).female_p5_mm))


#: Limits of the 14-joint skeleton built from :data:`ANSUR_II_PERCENTILES`.
LIMITS_14: tuple[Limit, ...] = build_limits()
#: Lowest ankle joint centre above the floor, metres (see :func:`build_ankle_clearance`).
ANKLE_CLEARANCE_M: float = build_ankle_clearance()


# ------------------------------------------------------------- survey files
_ALLOWED_BINOPS = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.divide}
_ALLOWED_CALLS = {"hypot": np.hypot}


def expression_columns(expression: str) -> set[str]:
    """ANSUR II column names used by an expression."""
    names = {n.id for n in ast.walk(ast.parse(expression, mode="eval")) if isinstance(n, ast.Name)}
    return names - set(_ALLOWED_CALLS)


def evaluate_expression(expression: str, columns: dict[str, np.ndarray]) -> np.ndarray:
    """Evaluate an arithmetic expression of column names (``+ - * /``, numbers, ``hypot``).

    Parameters
    ----------
    expression : str
    columns : dict of str to ndarray of shape (n_subjects,)

    Returns
    -------
    ndarray of shape (n_subjects,)

    Raises
    ------
    InputError
        If the expression uses anything else, or a column that is missing.
    """

    def ev(node):
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.BinOp) and type(node.op) in _ALLOWED_BINOPS:
            return _ALLOWED_BINOPS[type(node.op)](ev(node.left), ev(node.right))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            return -ev(node.operand)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return float(node.value)
        if isinstance(node, ast.Name):
            if node.id not in columns:
                raise InputError(f"expression {expression!r}", "a known column name", repr(node.id))
            return columns[node.id]
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                and node.func.id in _ALLOWED_CALLS and not node.keywords):
            return _ALLOWED_CALLS[node.func.id](*[ev(a) for a in node.args])
        raise InputError(f"expression {expression!r}", "column names, numbers, + - * / and hypot",
                         ast.dump(node))

    return np.asarray(ev(ast.parse(expression, mode="eval")), dtype=float)


def _read_columns(path: Path, names: set[str]) -> dict[str, np.ndarray]:
    """Numeric columns of one ANSUR II CSV (header matched case-insensitively)."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except OSError as e:
        raise InputError(str(path), "a readable ANSUR II CSV file",
                         f"{type(e).__name__}: {e}") from e
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = [h.strip().lower() for h in next(reader)]
    except StopIteration:
        raise InputError(str(path), "a header row", "an empty file") from None
    missing = sorted(names - set(header))
    if missing:
        raise InputError(f"{path}: header", f"columns {sorted(names)}", f"none named {missing}")
    idx = {n: header.index(n) for n in names}
    values = {n: [] for n in names}
    for row in reader:
        if not row:
            continue
        for n, i in idx.items():
            try:
                values[n].append(float(row[i]))
            except (ValueError, IndexError):
                found = repr(row[i]) if i < len(row) else "a short row"
                raise InputError(f"{path}: line {reader.line_num}, column {n}", "a number (mm)",
                                 found) from None
    if not values[next(iter(names))]:
        raise InputError(str(path), "at least one subject row", "none")
    return {n: np.asarray(v) for n, v in values.items()}


@dataclass(frozen=True)
class AnsurDerivation:
    """Limits recomputed from the ANSUR II CSV files.

    Attributes
    ----------
    percentiles : dict of str to SurveyPercentiles
        Raw survey percentiles (mm) of every expression in :data:`ANSUR_II_PERCENTILES`.
    limits : tuple of Limit
        :func:`build_limits` applied to them.
    ankle_clearance_m : float
        :func:`build_ankle_clearance` applied to them.
    n_male, n_female : int
        Subjects read.
    """

    percentiles: dict
    limits: tuple
    ankle_clearance_m: float
    n_male: int
    n_female: int


def derive_limits_from_ansur(male_csv: str | Path, female_csv: str | Path) -> AnsurDerivation:
    """Recompute the survey percentiles and the limits from ANSUR II CSV files.

    Parameters
    ----------
    male_csv, female_csv : str or Path
        ``ANSUR_II_MALE_Public.csv`` and ``ANSUR_II_FEMALE_Public.csv`` of the
        public release (one row per subject, measurements in mm).

    Returns
    -------
    AnsurDerivation

    Raises
    ------
    InputError
        If a file cannot be read, lacks a column, or holds a non-numeric value.

    Notes
    -----
    Each expression is evaluated per subject, then ``np.percentile`` (linear
    interpolation) gives the female 5th and male 95th percentiles.
    """
    exprs = list(ANSUR_II_PERCENTILES)
    needed = set().union(*(expression_columns(e) for e in exprs))
    male = _read_columns(Path(male_csv), needed)
    female = _read_columns(Path(female_csv), needed)
    pct = {}
    for e in exprs:
        f5 = float(np.percentile(evaluate_expression(e, female), MIN_PERCENTILE))
        m95 = float(np.percentile(evaluate_expression(e, male), MAX_PERCENTILE))
        pct[e] = SurveyPercentiles(e, f5, m95)
    return AnsurDerivation(pct, build_limits(pct), build_ankle_clearance(pct),
                           n_male=len(next(iter(male.values()))),
                           n_female=len(next(iter(female.values()))))


# ------------------------------------------------------------------- tables
def limits_markdown(limits: tuple[Limit, ...] = LIMITS_14) -> str:
    """The limits as a markdown table, left/right mirrors merged into one row."""
    rows: dict[tuple, list[str]] = {}
    for lim in limits:
        key = (lim.name, lim.min_m, lim.max_m, lim.source)
        rows.setdefault(key, []).append(f"{lim.joint_a}-{lim.joint_b}")
    out = ["| measure | joints | min (m) | max (m) | derivation (mm) |", "|---|---|---|---|---|"]
    for (name, lo, hi, src), pairs in rows.items():
        lo_s = "-" if lo == 0 else f"{lo:.2f}"
        out.append(f"| {name} | {', '.join(pairs)} | {lo_s} | {hi:.2f} | {src} |")
    return "\n".join(out)


def percentiles_markdown(percentiles: dict[str, SurveyPercentiles] | None = None) -> str:
    """The raw survey percentiles as a markdown table."""
    pct = ANSUR_II_PERCENTILES if percentiles is None else percentiles
    out = ["| ANSUR II expression | female p5 (mm) | male p95 (mm) |", "|---|---|---|"]
    out += [f"| `{p.expression}` | {p.female_p5_mm:.2f} | {p.male_p95_mm:.2f} |"
            for p in pct.values()]
    return "\n".join(out)


def limit_tables_markdown() -> str:
    """The tables of ``docs/anthropometry.md``: survey percentiles, limits, ankle clearance."""
    clearance = ("Ankle clearance (lowest ankle joint centre above the floor): "
                 f"{ANKLE_CLEARANCE_M:.2f} m")
    return f"{percentiles_markdown()}\n\n{limits_markdown()}\n\n{clearance}"
