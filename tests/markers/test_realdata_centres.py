"""Joint centres on the real C3D captures (skipped when ../shared/realdata is absent)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from toolkit.markers.functional import joint_centres, trajectories_from_c3d
from toolkit.markers.skeleton_fit import J14, harrington_hips

pytestmark = pytest.mark.realdata


def _file(*parts) -> Path:
    env = os.environ.get("TOOLKIT_REALDATA")
    root = Path(env) if env else Path(__file__).resolve().parents[3] / "shared" / "realdata"
    path = root.joinpath(*parts)
    if not path.is_file():
        pytest.skip(f"real data not found at {path}")
    return path


def test_right_hip_functional_centre_near_harrington():
    tr = trajectories_from_c3d(_file("c3d_functional", "right_hip.c3d"))
    res = joint_centres(tr)
    assert res.method[J14["r_hip"]] == "score" and res.rom_deg[J14["r_hip"]] > 40
    P = {lab: tr.positions[:, i] for i, lab in enumerate(tr.labels)}
    _, rh = harrington_hips(P["LASIS"], P["RASIS"], P["LPSIS"], P["RPSIS"])
    d = np.nanmedian(np.linalg.norm(res.joints[:, J14["r_hip"]] - rh, axis=1))
    assert d < 0.025, d
    assert any("functional centres need movement" in m for m in res.messages)  # the left side stood still


def test_unlabelled_arm_subsets_and_centres():
    tr = trajectories_from_c3d(_file("c3d_functional", "arm-4-2-3_clean_120fps.c3d"))
    res = joint_centres(tr)
    assert not res.labelled
    assert sorted(len(s) for s in res.subsets.values()) == [2, 3, 4]
    assert len(res.fits) == 2 and all(f.residual_m < 0.015 for f in res.fits.values())


def test_plug_in_gait_walk_knees_refused_and_static_trial_generic():
    from toolkit.markers.marker_sets import get_marker_set

    labels = get_marker_set("plug-in-gait").labels
    tr = trajectories_from_c3d(_file("c3d_plugin_gait", "Movement_trial.c3d"))
    res = joint_centres(tr.subset([lab for lab in tr.labels if lab in labels]))
    # 2.7 s of walking: the shank markers' circles do not fix where the knee axis lies (refused, not wrong)
    for name in ("l_knee", "r_knee"):
        assert res.method[J14[name]] == "anatomical"
        assert any(m.startswith(name) and "does not fix where the axis lies" in m for m in res.messages)
    st = trajectories_from_c3d(_file("c3d_plugin_gait", "Static_trial.c3d"))
    rs = joint_centres(st.subset([lab for lab in st.labels if lab in labels]))
    assert set(rs.method) <= {"anatomical", "template", "none"}
    assert any("functional centres need movement" in m for m in rs.messages)


def test_plug_in_gait_knees_and_ankles_by_the_chord_with_the_measured_widths():
    """Where the functional knee is refused (the walk above), the knee and ankle come from Plug-in Gait's own
    chord rule with the file's ``PROCESSING`` knee and ankle widths: near Plug-in Gait's outputs in the file
    (their hips differ: Harrington's regression here)."""
    from toolkit.markers.skeleton_fit import anatomical_joints

    tr = trajectories_from_c3d(_file("c3d_plugin_gait", "Movement_trial.c3d"))
    assert tr.measurements["LKneeWidth"] == pytest.approx(0.144)
    P = {lab: tr.positions[:, i] for i, lab in enumerate(tr.labels)}
    a = anatomical_joints(tr.labels, tr.positions, measurements=tr.measurements)
    for s in "LR":
        knee = np.nanmedian(np.linalg.norm(a[:, J14[f"{s.lower()}_knee"]] - P[s + "FEO"], axis=1))
        ankle = np.nanmedian(np.linalg.norm(a[:, J14[f"{s.lower()}_ankle"]] - P[s + "TIO"], axis=1))
        assert knee < 0.012 and ankle < 0.005, (s, knee, ankle)
    # with Plug-in Gait's own hip centre (LFEP) the chord gives its knee exactly
    from toolkit.markers.skeleton_fit import chord

    k = chord(P["LFEP"], P["LTHI"], P["LKNE"], tr.measurements["LKneeWidth"] / 2 + 0.007)
    assert np.nanmax(np.linalg.norm(k - P["LFEO"], axis=1)) < 1e-4
