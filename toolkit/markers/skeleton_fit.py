"""The generic 14-joint skeleton scaled to the performer, and joint estimates from markers alone.

Two estimates of a joint from the markers of one frame (no motion needed),
used for the joints no centre of rotation gives (neck, head, wrists), as the
fallback of a joint that did not move enough, and to place a hinge's centre
on its axis:

* **Template regression** (a known marker set): the marker set's placements
  (:class:`toolkit.markers.marker_sets.MarkerSet`) on the generic skeleton
  (:class:`toolkit.anthropometry.BodyProportions`) of a fitted stature give,
  for each segment, where its joints sit relative to its markers; a rigid fit
  of those template markers to the markers seen (Kabsch) carries the joints
  into the frame.  The stature is the one whose templates fit the markers best.
* **Anatomical rules** (labels of other marker sets, e.g. the ISB-style names
  of ``c3d_functional/right_hip.c3d``): hip centres from the pelvis markers by
  the regression of Harrington et al. 2007 ("Prediction of the hip joint
  centre in adults, children, and patients with cerebral palsy based on
  magnetic resonance imaging", J Biomech 40:595-602), knee, ankle, elbow and
  wrist centres at the midpoints of the epicondyles, malleoli and styloids.
"""

from __future__ import annotations

import re

import numpy as np

from toolkit.anthropometry.proportions import BodyProportions
from toolkit.errors import InputError
from toolkit.markers.rigid import _quiet, rigid_motions
from toolkit.skeleton import SKELETON_14

J14 = {n: i for i, n in enumerate(SKELETON_14.joint_names)}

#: Segment of a marker from its label, for files that do not follow a known marker set:
#: (regular expression on the label, segment; ``X`` in the segment is the label's side).
LABEL_RULES = (
    (r"^[LR](ASI|ASIS|PSI|PSIS)$", "pelvis"), (r"^SACR?$", "pelvis"),
    (r"^(C7|T10|CLAV|STRN|RBAK|SUP|STR|T8|XIP|XP|IJ|PX)$", "thorax"),
    (r"^[LR](SHO|A)$", "thorax"),
    (r"^([LR](FHD|BHD|TEMP)|HV|OCC|SEL)$", "head"),
    (r"^([LR])(THI\d*|KNE|LFE|MFE|TH\d|GT)$", "X_thigh"),
    (r"^([LR])(TIB|ANK|LEG\d|SK\d|LM|MM|SPH|ATT|HF|TT)$", "X_shank"),
    (r"^([LR])(HEE|TOE|CAL|MFH\d|MT\d|TT2|FM\d)$", "X_foot"),
    (r"^([LR])(UPA|ELB|ARM\d|AMR\d|UA\d|LHE|MHE)$", "X_upperarm"),
    (r"^([LR])(FRM|WRA|WRB|FARM\d|FA\d|US|RS)$", "X_forearm"),
    (r"^([LR])(FIN|HMH\d|FT3)$", "X_hand"),
)


def segment_of_label(label: str) -> str | None:
    """The body segment of a marker label by :data:`LABEL_RULES`, or None."""
    for pattern, seg in LABEL_RULES:
        m = re.match(pattern, label)
        if m:
            side = label[0].lower()
            return seg.replace("X_", f"{side}_") if seg.startswith("X_") else seg
    return None


def _p(positions: dict, *names):
    """The first of ``names`` present in ``positions`` (label -> (T, 3)), or None."""
    for n in names:
        if n in positions:
            return positions[n]
    return None


def _mid(a, b):
    return None if a is None or b is None else 0.5 * (a + b)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def harrington_hips(lasi, rasi, lpsi, rpsi) -> tuple[np.ndarray, np.ndarray]:
    """Hip joint centres by the regression of Harrington et al. 2007 (J Biomech 40:595).

    In the pelvis frame (origin mid-ASIS, x anterior, y superior, z right),
    with PW the inter-ASIS distance and PD the ASIS-to-PSIS depth (mm):
    x = -0.24 PD - 9.9, y = -0.30 PW - 10.9, z = +-(0.33 PW + 7.3).

    Parameters
    ----------
    lasi, rasi, lpsi, rpsi : ndarray of shape (T, 3)
        Metres.

    Returns
    -------
    left, right : ndarray of shape (T, 3)
        Metres, NaN where a marker is missing.
    """
    o = 0.5 * (lasi + rasi)
    z = _unit(rasi - lasi)
    back = 0.5 * (lpsi + rpsi)
    x = o - back
    x = _unit(x - np.sum(x * z, axis=-1, keepdims=True) * z)
    y = np.cross(z, x)
    pw = np.linalg.norm(rasi - lasi, axis=-1, keepdims=True) * 1000.0
    pd = np.sum((o - back) * x, axis=-1, keepdims=True) * 1000.0
    base = o + ((-0.24 * pd - 9.9) * x + (-0.30 * pw - 10.9) * y) / 1000.0
    lat = (0.33 * pw + 7.3) / 1000.0 * z
    return base - lat, base + lat


def _across(P, joint, s, other, pig):
    """Unit vector from side ``s`` towards the other side: the pelvis's (legs) or the shoulders' (arms)
    left-right axis, else the direction to the other side's marker."""
    pairs = (("LASI", "RASI"), ("LASIS", "RASIS")) if joint in ("knee", "ankle") else (("LSHO", "RSHO"), ("LA", "RA"))
    for left, right in pairs:
        if left in P and right in P:
            v = _unit(P[right] - P[left])
            return v if s == "L" else -v
    if (s + pig) in P and (other + pig) in P:
        return _unit(P[other + pig] - P[s + pig])
    return None


#: Plug-in Gait's marker radius where the file does not give ``MarkerDiameter``, metres.
MARKER_RADIUS_M = 0.007


def chord(proximal: np.ndarray, wand: np.ndarray, lateral: np.ndarray, offset_m: float) -> np.ndarray:
    """Plug-in Gait's chord rule: a joint centre from the joint above it, a wand marker and the lateral marker.

    The centre ``X`` lies in the plane of ``proximal``, ``wand`` and
    ``lateral``, on the side away from the wand, ``offset_m`` from ``lateral``
    (half the joint's width plus the marker radius), with the angle
    ``proximal - X - lateral`` a right angle (Davis et al. 1991, "A gait
    analysis data collection and reduction technique", *Hum Mov Sci*
    10:575-587; Vicon's Plug-in Gait knee and ankle).

    Parameters
    ----------
    proximal, wand, lateral : ndarray of shape (T, 3)
        Metres: e.g. the hip centre, ``THI`` and ``KNE`` for the knee; the knee
        centre, ``TIB`` and ``ANK`` for the ankle.
    offset_m : float

    Returns
    -------
    ndarray of shape (T, 3)
        Metres; NaN where a point is missing or the geometry is degenerate.
    """
    a = np.asarray(proximal, float) - lateral
    length = np.linalg.norm(a, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        ah = a / length
        t = np.asarray(wand, float) - lateral
        n = t - np.sum(t * ah, axis=-1, keepdims=True) * ah
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        cos = offset_m / length
        sin = np.sqrt(1.0 - cos ** 2)  # NaN where the joint above is closer than the offset
    out = lateral + offset_m * (cos * ah - sin * n)
    out[~np.isfinite(out).all(axis=-1)] = np.nan
    return out


def anatomical_joints(labels, positions: np.ndarray, *, height_m: float = 1.75,
                      measurements: dict | None = None) -> np.ndarray:
    """Joint estimates from anatomical landmarks named in the labels.

    Hips: :func:`harrington_hips` (``LASI/RASI/LPSI/RPSI`` or ``*ASIS/*PSIS``);
    knees: midpoint of ``LFE/MFE`` epicondyles, else Plug-in Gait's
    :func:`chord` from the hip centre, ``THI`` and ``KNE`` (the measured
    ``LKneeWidth``/``RKneeWidth`` of ``measurements`` or a generic 0.057 x
    stature; ``MarkerDiameter`` or :data:`MARKER_RADIUS_M`), else ``KNE``
    moved medially (along the pelvis's left-right axis) by half that width
    plus the marker radius; ankles likewise from ``LM/SPH`` (or ``MM``), the
    chord from the knee centre, ``TIB`` and ``ANK``, or ``ANK`` (0.040 x
    stature, ``*AnkleWidth``); elbows from ``LHE/MHE``
    or ``ELB`` (0.040 x stature); wrists: midpoint of ``WRA/WRB`` or ``US/RS``;
    shoulders: the acromion marker (``SHO`` or ``A``) 0.025 x stature below;
    neck: midpoint of ``C7`` and ``CLAV`` (or ``SUP``); head: mean of the head
    markers.

    Parameters
    ----------
    labels : sequence of str (M)
    positions : ndarray of shape (T, M, 3)
        Metres.
    height_m : float
        Stature for the generic widths.
    measurements : dict of str to float, optional
        The subject's measured widths, metres (``LKneeWidth``, ``RAnkleWidth``,
        ``MarkerDiameter`` ...: :attr:`toolkit.io.c3d.C3DPoints.measurements`).

    Returns
    -------
    ndarray of shape (T, 14, 3)
        Metres, NaN for joints without the landmarks.
    """
    pos = np.asarray(positions, dtype=float)
    P = {lab: pos[:, i] for i, lab in enumerate(labels)}
    out = np.full((pos.shape[0], 14, 3), np.nan)
    asis = [_p(P, "LASI", "LASIS"), _p(P, "RASI", "RASIS")]
    psis = [_p(P, "LPSI", "LPSIS"), _p(P, "RPSI", "RPSIS")]
    sacr = _p(P, "SACR", "SACRUM")
    if sacr is not None and psis[0] is None:
        psis = [sacr, sacr]
    if all(a is not None for a in asis + psis):
        out[:, J14["l_hip"]], out[:, J14["r_hip"]] = harrington_hips(asis[0], asis[1], psis[0], psis[1])
    measured = dict(measurements or {})
    radius = measured.get("MarkerDiameter", 2 * MARKER_RADIUS_M) / 2
    widths = {"knee": 0.057, "ankle": 0.040, "elbow": 0.040}
    pairs = {"knee": (("LFE", "MFE"), "KNE"), "ankle": (("LM", "SPH"), "ANK"), "elbow": (("LHE", "MHE"), "ELB")}
    #: the chord's joint above and wand marker per joint (Plug-in Gait's lower limb)
    chords = {"knee": ("hip", "THI"), "ankle": ("knee", "TIB")}
    for s in "LR":
        other = "R" if s == "L" else "L"
        for joint, ((lat, med), pig) in pairs.items():
            j = J14[f"{s.lower()}_{joint}"]
            width = measured.get(f"{s}{joint.capitalize()}Width", widths[joint] * height_m)
            m = _mid(_p(P, s + lat), _p(P, s + med, s + "MM" if joint == "ankle" else s + med))
            if m is None and (s + pig) in P:  # the Plug-in Gait lateral marker: chord, else moved medially
                offset = width / 2 + radius
                across = _across(P, joint, s, other, pig)
                m = P[s + pig] + across * offset if across is not None else np.full_like(P[s + pig], np.nan)
                if joint in chords and (s + chords[joint][1]) in P:
                    above = out[:, J14[f"{s.lower()}_{chords[joint][0]}"]]
                    c = chord(above, P[s + chords[joint][1]], P[s + pig], offset)
                    m = np.where(np.isfinite(c), c, m)
            if m is not None:
                out[:, j] = m
        w = _mid(_p(P, s + "WRA", s + "US"), _p(P, s + "WRB", s + "RS"))
        if w is not None:
            out[:, J14[f"{s.lower()}_wrist"]] = w
        sho = _p(P, s + "SHO", s + "A")
        if sho is not None:
            up = np.array([0.0, 0.0, 1.0])
            out[:, J14[f"{s.lower()}_shoulder"]] = sho - 0.025 * height_m * up
    neck = _mid(_p(P, "C7"), _p(P, "CLAV", "SUP"))
    if neck is not None:
        out[:, J14["neck"]] = neck
    head = [P[n] for n in ("LFHD", "RFHD", "LBHD", "RBHD") if n in P] or \
        [P[n] for n in ("LTEMP", "RTEMP") if n in P]
    if head:
        out[:, J14["head"]] = np.mean(head, axis=0)
    return out


# ------------------------------------------------------------------ template regression
def template_frames(marker_set, props: BodyProportions, labels) -> tuple[np.ndarray, np.ndarray, dict]:
    """The marker set's markers and joints at the neutral pose, for a body of ``props``.

    Parameters
    ----------
    marker_set : MarkerSet
    props : BodyProportions
    labels : sequence of str
        The labels whose template positions are wanted (M); those not in the set get NaN.

    Returns
    -------
    markers : ndarray of shape (M, 3)
        World positions at the neutral pose, metres.
    joints : ndarray of shape (14, 3)
    frames : dict of str to (R (3, 3), origin (3,))
        Each segment's frame at the neutral pose.
    """
    from toolkit.markers.marker_sets import segment_origins, segment_rotations
    from toolkit.motion.kinematics import Pose14, forward_kinematics

    pose = Pose14.neutral(1)
    joints = forward_kinematics(props, pose)
    world = marker_set.positions(joints, pose=pose)[0]
    rots = segment_rotations(pose)
    origins = segment_origins(joints)
    out = np.full((len(labels), 3), np.nan)
    for i, lab in enumerate(labels):
        if lab in marker_set.labels:
            out[i] = world[marker_set.index(lab)]
    frames = {k: (rots[k][0], origins[k][0]) for k in rots}
    return out, joints[0], frames


#: Joints carried by each segment's template (segment -> joints), for the regression.
SEGMENT_JOINTS = {
    "pelvis": ("l_hip", "r_hip"), "thorax": ("neck", "l_shoulder", "r_shoulder"), "head": ("head", "neck"),
    **{f"{s}_{seg}": tuple(f"{s}_{j}" for j in js) for s in "lr" for seg, js in
       (("thigh", ("hip", "knee")), ("shank", ("knee", "ankle")), ("foot", ("ankle",)),
        ("upperarm", ("shoulder", "elbow")), ("forearm", ("elbow", "wrist")), ("hand", ("wrist",)))},
}


def template_joints(positions: np.ndarray, groups: dict, template_markers: np.ndarray,
                    template_joints14: np.ndarray, *, max_rms_m: float = 0.02,
                    max_disagreement_m: float = 0.03) -> tuple[np.ndarray, dict]:
    """Joints carried into each frame by rigid fits of each segment's template markers.

    Parameters
    ----------
    positions : ndarray of shape (T, M, 3)
        Markers seen, metres, NaN where missing.
    groups : dict of str to list of int
        Segment -> marker indices to fit (at least three, with template positions).
    template_markers : ndarray of shape (M, 3)
        The template's markers (world, neutral pose).
    template_joints14 : ndarray of shape (14, 3)
    max_rms_m : float
        A segment's frame whose fit leaves a larger RMS carries no joint (mislabelled markers).
    max_disagreement_m : float
        Where two segments place their common joint farther than this from
        their mean (a segment whose labels are swapped with another's still
        fits rigidly), the joint is NaN in that frame rather than wrong.

    Returns
    -------
    joints : ndarray of shape (T, 14, 3)
        Mean over the segments carrying each joint; NaN where none is seen or they disagree.
    rms : dict of str to float
        Median fit RMS of each segment, metres.
    """
    t = positions.shape[0]
    est = [[] for _ in range(14)]  # per joint, the (T, 3) estimates of the segments carrying it
    rms = {}
    for seg, idx in groups.items():
        idx = [i for i in idx if np.isfinite(template_markers[i]).all()]
        if len(idx) < 3 or seg not in SEGMENT_JOINTS:
            continue
        ref = template_markers[idx]
        rot, trans, r = rigid_motions(ref, positions[:, idx])
        rot[~(r <= max_rms_m)] = np.nan  # a frame the template does not fit (mislabels): no joint from it
        with _quiet():
            rms[seg] = float(np.nanmedian(r)) if np.isfinite(r).any() else float("nan")
        for name in SEGMENT_JOINTS[seg]:
            est[J14[name]].append(np.einsum("tij,j->ti", rot, template_joints14[J14[name]]) + trans)
    joints = np.full((t, 14, 3), np.nan)
    for j, e in enumerate(est):
        if not e:
            continue
        e = np.stack(e)  # (S, T, 3)
        with _quiet():
            joints[:, j] = np.nanmean(e, axis=0)
            if len(e) > 1:  # segments that disagree on their common joint: mislabelled markers, no joint
                spread = np.nanmax(np.linalg.norm(e - joints[None, :, j], axis=-1), axis=0)
                joints[spread > max_disagreement_m, j] = np.nan
    return joints, rms


def fit_stature(positions: np.ndarray, groups: dict, marker_set, labels, *,
                bounds=(1.4, 2.1), frames: int = 30) -> float:
    """The stature whose template fits the markers best (sum of segment RMS over a few frames).

    Parameters
    ----------
    positions : ndarray of shape (T, M, 3)
    groups : dict of str to list of int
    marker_set : MarkerSet
    labels : sequence of str (M)
    bounds : (float, float)
        Statures searched (scipy's bounded scalar minimisation), metres.
    frames : int
        At most this many frames (evenly spread) are used.

    Returns
    -------
    float
        Metres.
    """
    from scipy.optimize import minimize_scalar

    sel = np.unique(np.linspace(0, positions.shape[0] - 1, min(frames, positions.shape[0])).astype(int))
    sub = positions[sel]
    # the template of a 1.75 m body scaled uniformly stands in for each stature's own (one placement
    # on the body mesh instead of one per stature; the rigid fits do not see the common origin)
    h0 = 1.75
    tm0, tj0, _ = template_frames(marker_set, BodyProportions.from_height(h0), labels)

    def cost(h):
        _, rms = template_joints(sub, groups, tm0 * (h / h0), tj0 * (h / h0))
        vals = [v for v in rms.values() if np.isfinite(v)]
        return float(np.sum(np.square(vals))) if vals else 1e9

    res = minimize_scalar(cost, bounds=bounds, method="bounded", options={"xatol": 0.002})
    return float(res.x)


def stature_from_legs(joints: np.ndarray) -> float:
    """Stature from the leg length of 14 joints (thigh + shank = 0.471 x stature, ANSUR II medians).

    Parameters
    ----------
    joints : ndarray of shape (T, 14, 3)

    Returns
    -------
    float
        Metres, clipped to 1.4-2.1; 0.0 when no leg is seen.
    """
    from toolkit.anthropometry.proportions import STATURE_RATIOS as r

    legs = []
    for s in "lr":
        h, k, a = (joints[:, J14[f"{s}_{n}"]] for n in ("hip", "knee", "ankle"))
        v = np.linalg.norm(h - k, axis=-1) + np.linalg.norm(k - a, axis=-1)
        legs.append(v[np.isfinite(v)])
    v = np.concatenate(legs)
    if not v.size:
        return 0.0
    return float(np.clip(np.median(v) / (r["hip_height"] - r["ankle_height"]), 1.4, 2.1))


def bone_lengths(joints: np.ndarray) -> dict:
    """Median length of every bone of :data:`SKELETON_14` over frames, metres (NaN if never seen)."""
    lengths = SKELETON_14.bone_lengths(np.nan_to_num(joints, nan=np.nan))
    with _quiet():
        med = np.nanmedian(lengths.reshape(-1, lengths.shape[-1]), axis=0)
    return {name: float(v) for name, v in zip(SKELETON_14.bone_names, med)}


def generic_lengths(height_m: float) -> dict:
    """Bone lengths of the generic skeleton of stature ``height_m`` (metres)."""
    if not np.isfinite(height_m):
        raise InputError("height_m", "a finite stature", repr(height_m))
    rest = BodyProportions.from_height(height_m).rest_pose()
    return bone_lengths(rest[None])
