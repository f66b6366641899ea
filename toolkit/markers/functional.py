"""Joint centres from labelled or unlabelled marker trajectories.

:func:`joint_centres` is the step after labelling (or after reading a C3D):

1. **Subsets.** With labels, each body segment's markers (from the marker
   set, or :data:`toolkit.markers.skeleton_fit.LABEL_RULES`), checked for
   rigidity (:func:`toolkit.markers.rigid.check_segments`: a marker that does
   not move with its segment mates is dropped from the fits).  A limb segment with
   fewer than three markers borrows a marker of its parent limb segment that
   moves rigidly with it (a marker on the joint axis, e.g. Plug-in Gait's ``KNE`` for the
   shank) and, for a limb, the centre already found at its proximal joint
   (the hip for the thigh, as Plug-in Gait chains its segments).  Without
   labels, :func:`toolkit.markers.rigid.find_rigid_subsets`.
2. **Centres of rotation** between adjacent subsets
   (:mod:`toolkit.markers.centres`): SCoRE for ball joints (hips, shoulders),
   SARA for hinges (knees, elbows, ankles) and for a ball joint that only
   moved about one axis (walking hips), with the centre placed on the axis
   nearest the generic skeleton's joint; a child with fewer than three markers
   (Plug-in Gait's thigh and upper arm) by a sphere fit in the parent's frame.
   A joint that moved less than ``min_rom_deg`` keeps the generic skeleton's
   joint, and the result says so.
3. **Skeleton.** The 14 joints: the centres found, the generic skeleton's
   joints (template regression of the marker set scaled to the performer, or
   anatomical rules) for the others; bone lengths for ``skeleton.json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import toolkit.markers.centres as _c
import toolkit.markers.rigid as _r
import toolkit.markers.skeleton_fit as _s
from toolkit.errors import InputError
from toolkit.observe import as_observer
from toolkit.skeleton import SKELETON_14

#: Joints found from the motion: (joint, parent segment, child segment, kind), proximal ones first.
FUNCTIONAL_JOINTS = tuple(
    (f"{s}_{j}", parent.replace("X", s), child.replace("X", s), kind)
    for j, parent, child, kind in (
        ("hip", "pelvis", "X_thigh", "ball"), ("shoulder", "thorax", "X_upperarm", "ball"),
        ("knee", "X_thigh", "X_shank", "hinge"), ("elbow", "X_upperarm", "X_forearm", "hinge"),
        ("ankle", "X_shank", "X_foot", "hinge"))
    for s in "lr")
#: The parent segment of each limb segment.
PARENT = {ch: p for _j, p, ch, _k in FUNCTIONAL_JOINTS}
#: The joint at the proximal end of a limb segment (its centre may serve as a virtual marker).
PROXIMAL = {ch: j for j, _p, ch, _k in FUNCTIONAL_JOINTS}

#: How each joint was placed.
JOINT_METHODS = ("score", "sara", "sphere", "circle", "template", "anatomical", "none")


@dataclass(frozen=True)
class JointCentresConfig:
    """Options of :func:`joint_centres`.

    Attributes
    ----------
    marker_set : str
        ``"auto"`` (the known set most of whose labels are present, else
        :data:`~toolkit.markers.skeleton_fit.LABEL_RULES`), a set name, or
        ``"none"`` (find rigid subsets without labels).
    min_rom_deg : float
        Least range of motion (degrees, largest principal extent) for a
        functional centre; less keeps the generic skeleton's joint.
    planar_ratio : float
        A ball joint whose second range of motion is below this share of the
        first moved about one axis only and is treated as a hinge (SARA).
    rigid_tolerance_m : float
        Median pairwise distance std under which a neighbour's marker counts
        as rigid with a segment (borrowed markers), metres.
    segment_tolerance_m : float
        Median distance std to its segment mates above which a labelled
        marker is dropped from the fits, metres.
    subset_threshold_m : float
        Distance-std cut of the clustering without labels, metres.
    max_joint_residual_m : float
        Without labels: a pair of subsets is a joint only if its SCoRE
        residual is below this, metres.
    max_residual_m : float
        With labels: a functional centre whose residual exceeds this (the
        segments' markers do not move as two rigid bodies linked at a point:
        soft tissue, few and nearly collinear markers, mislabels) is not
        used; the generic skeleton's joint is kept and the result says so.
    max_hinge_conditioning : float
        A SARA fit whose two smallest singular values are closer than this
        ratio did not see a clean hinge (the axis is not determined); it is
        not used either.
    max_axis_spread_m : float
        Circle fits (:func:`toolkit.markers.centres.circle_axis`): each child
        marker's own circle centre may lie this far (RMS, metres) from the
        common one; farther, the motion does not fix where the axis lies
        (short arcs, soft tissue) and the fit is not used.
    max_generic_distance_m : float
        A functional centre farther than this (median over frames, metres)
        from the marker set template's joint is not used (mislabelled markers
        that still move rigidly); 0 = no such check.  Not applied to the
        anatomical rules' joints (files from elsewhere), which are cruder.
    height_m : float
        Performer's stature, metres; 0 = fitted from the markers.
    """

    marker_set: str = "auto"
    min_rom_deg: float = 20.0
    planar_ratio: float = 0.25
    rigid_tolerance_m: float = 0.010
    segment_tolerance_m: float = 0.02
    subset_threshold_m: float = 0.015
    max_joint_residual_m: float = 0.03
    max_residual_m: float = 0.015
    max_hinge_conditioning: float = 0.2
    max_axis_spread_m: float = 0.005
    max_generic_distance_m: float = 0.04
    height_m: float = 0.0

    def __post_init__(self):
        for name in ("rigid_tolerance_m", "segment_tolerance_m", "subset_threshold_m", "max_joint_residual_m",
                     "max_residual_m", "max_hinge_conditioning", "planar_ratio", "max_axis_spread_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise InputError(f"JointCentresConfig.{name}", "a positive number", repr(v))
        for name in ("min_rom_deg", "max_generic_distance_m", "height_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise InputError(f"JointCentresConfig.{name}", "a number >= 0", repr(v))
        if self.height_m and not 1.0 <= self.height_m <= 2.5:
            raise InputError("JointCentresConfig.height_m (--height)", "0 (fitted) or a stature of 1.0-2.5 m",
                             repr(self.height_m))
        if not isinstance(self.marker_set, str) or not self.marker_set:
            raise InputError("JointCentresConfig.marker_set", "'auto', 'none' or a marker set's name",
                             repr(self.marker_set))


@dataclass
class JointCentresResult:
    """What :func:`joint_centres` found.

    Attributes
    ----------
    names : tuple of str
        :data:`toolkit.skeleton.JOINTS_14`.
    joints : ndarray of shape (T, 14, 3)
        Metres, NaN where a joint could not be placed.
    method : tuple of str
        Per joint, one of :data:`JOINT_METHODS`.
    residual_m : ndarray of shape (14,)
        Functional centres: RMS disagreement of the two segments' estimates
        (sphere fit: of the radii), metres; NaN for other joints.
    rom_deg : ndarray of shape (14,)
        Range of motion seen at each functional joint (largest principal extent), degrees; NaN if not measured.
    fits : dict of str to CentreFit
        The functional fits by joint name (unlabelled: by subset pair ``"S0-S1"``).
    subsets : dict of str to tuple of int
        Marker indices used for each segment (labelled) or subset (unlabelled).
    height_m : float
        Stature of the scaled generic skeleton, metres.
    lengths : dict of str to float
        Bone lengths of the skeleton (median over frames of the joints; the
        scaled generic skeleton's where a bone's joints are never seen), metres.
    messages : list of str
        What the caller should know (joints left at the generic skeleton, markers dropped).
    labelled : bool
        Whether segments came from labels.
    marker_set : str
        The marker set used (or ``"labels"`` for :data:`LABEL_RULES`, ``"none"``).
    generic : ndarray of shape (T, 14, 3)
        The scaled generic skeleton's joints from the markers (regression).
    """

    names: tuple
    joints: np.ndarray
    method: tuple
    residual_m: np.ndarray
    rom_deg: np.ndarray
    fits: dict
    subsets: dict
    height_m: float
    lengths: dict
    messages: list = field(default_factory=list)
    labelled: bool = True
    marker_set: str = "none"
    generic: np.ndarray | None = None

    def summary(self) -> dict:
        """Per joint: method, residual (mm), range of motion (degrees); JSON-ready."""
        def num(v, scale, digits):
            return None if not np.isfinite(v) else round(scale * float(v), digits)

        out = {}
        for j, name in enumerate(self.names):
            out[name] = {"method": self.method[j], "residual_mm": num(self.residual_m[j], 1e3, 2),
                         "rom_deg": num(self.rom_deg[j], 1.0, 1)}
        for key, fit in self.fits.items():
            if key not in out:
                out[key] = {"method": fit.method, "residual_mm": round(1e3 * fit.residual_m, 2),
                            "rom_deg": round(float(fit.rom_deg[0]), 1)}
        return out


def _choose_marker_set(labels, name: str):
    from toolkit.markers.marker_sets import MARKER_SETS, get_marker_set

    if name == "none":
        return None
    if name != "auto":
        return get_marker_set(name)
    best, share = None, 0.0
    for ms in MARKER_SETS.values():
        s = np.mean([lab in labels for lab in ms.labels])
        if s > share:
            best, share = ms, s
    return best if share >= 0.6 else None


def _segment_groups(traj, mset) -> dict:
    if traj.segments is not None:
        segs = traj.segments
    elif mset is not None:
        segs = tuple(mset.segments[mset.labels.index(lab)] if lab in mset.labels else None for lab in traj.labels)
    else:
        segs = tuple(_s.segment_of_label(lab) for lab in traj.labels)
    groups = {}
    for i, seg in enumerate(segs):
        if seg is not None:
            groups.setdefault(seg, []).append(i)
    return groups


def _extend(groups: dict, std: np.ndarray, tol: float) -> dict:
    """Limb segments of fewer than three markers borrow their parent limb's markers rigid with them."""
    out = {k: list(v) for k, v in groups.items()}
    for seg, idx in groups.items():
        if len(idx) >= 3 or not idx:
            continue
        cands = []
        parent = PARENT.get(seg)
        if parent is None or parent in ("pelvis", "thorax"):
            continue
        for m in groups.get(parent, ()):
            cands.append((float(np.median(std[m, idx])), m))
        for d, m in sorted(cands):
            if len(out[seg]) >= 3 or not d <= tol:
                break
            out[seg].append(m)
    return out


#: A frame whose subset fit leaves this RMS (metres) after the outlier pass has no motion (mislabels).
FRAME_RMS_M = 0.01


def _motion(pos: np.ndarray):
    """(rotations, translations, reference shape) of a subset's markers (T, K, 3), or None."""
    if pos.shape[1] < 3:
        return None
    try:
        ref = _r.reference_shape(pos)
    except InputError:
        return None
    rot, trans, rms = _r.rigid_motions(ref, pos)
    bad = ~(rms <= FRAME_RMS_M)
    rot[bad], trans[bad] = np.nan, np.nan
    if np.isfinite(trans).all(axis=1).sum() < 3:
        return None
    return rot, trans, ref


#: A subset whose centred shape has its second singular value below this share of the first lies
#: nearly on a line: its rotation about that line is decided by the skin noise, not by the markers.
COLLINEAR_RATIO = 0.1


def _nearly_collinear(pos: np.ndarray) -> bool:
    """Whether a subset's markers (T, K, 3) lie nearly on one line (:data:`COLLINEAR_RATIO`)."""
    if pos.shape[1] < 3:
        return True
    try:
        ref = _r.reference_shape(pos)
    except InputError:
        return True
    ref = ref[np.isfinite(ref).all(axis=1)]
    s = np.linalg.svd(ref - ref.mean(axis=0), compute_uv=False) if len(ref) >= 3 else np.zeros(2)
    return not s[1] >= COLLINEAR_RATIO * s[0]


def _fit_joint(kind, parent_pos, child_pos, anchor, config, *, trusted: bool = True, n_own: int | None = None):
    """One functional joint: (CentreFit or None, why-not message).

    ``trusted``: the anchor is the marker set's template (a synthetic capture), close enough to the
    joint that a functional centre far from it means mislabelled markers; an anatomical rule's anchor
    (a file from elsewhere) is not used for that check.  ``n_own``: the first ``n_own`` markers of
    ``child_pos`` are the child's own (the others borrowed from the parent); default all.

    A hinge whose child has no well-determined rigid motion (fewer than three markers, or markers
    nearly on one line, :func:`_nearly_collinear`) gets its axis from the circles its own markers
    describe in the parent's frame (:func:`toolkit.markers.centres.circle_axis`); other hinges SARA.
    """
    pm = _motion(parent_pos)
    if pm is None:
        return None, "its parent segment has fewer than three markers seen together"
    cm = _motion(child_pos)
    own = child_pos if n_own is None else child_pos[:, :n_own]
    try:
        if kind == "hinge" and own.shape[1] > 0 and (cm is None or _nearly_collinear(child_pos)):
            fit = _c.circle_axis(pm[0], pm[1], own, anchor=anchor, parent_reference=pm[2],
                                 parent_points=parent_pos)
        elif cm is None:
            if child_pos.shape[1] == 0:
                return None, "its child segment has no markers"
            fit = _c.sphere_centre(pm[0], pm[1], child_pos, anchor=anchor)
        else:
            rom = _c.range_of_motion(pm[0], cm[0])
            planar = rom[1] < config.planar_ratio * rom[0]
            if kind == "hinge" or planar:
                fit = _c.sara(pm[0], pm[1], cm[0], cm[1], anchor=anchor)
            else:
                fit = _c.score(pm[0], pm[1], cm[0], cm[1], anchor=anchor)
    except InputError as e:
        return None, str(e)
    if not fit.rom_deg[0] >= config.min_rom_deg:
        return fit, (f"it moved {fit.rom_deg[0]:.0f} degrees, less than {config.min_rom_deg:.0f}: "
                     "functional centres need movement")
    if not fit.residual_m <= config.max_residual_m:
        return fit, (f"the {fit.method} fit's residual {1e3 * fit.residual_m:.0f} mm exceeds "
                     f"{1e3 * config.max_residual_m:.0f} mm")
    if fit.method in ("sara", "circle") and not fit.conditioning <= config.max_hinge_conditioning:
        return fit, (f"no clean hinge axis (singular value ratio {fit.conditioning:.2f} > "
                     f"{config.max_hinge_conditioning:.2f})")
    if fit.method == "circle" and not fit.axis_spread_m <= config.max_axis_spread_m:
        return fit, (f"the markers' circles put the axis {1e3 * fit.axis_spread_m:.0f} mm apart (over "
                     f"{1e3 * config.max_axis_spread_m:.0f} mm: the motion does not fix where the axis lies)")
    if config.max_generic_distance_m > 0 and anchor is not None and trusted:
        with _r._quiet():
            d = float(np.nanmedian(np.linalg.norm(fit.centre - anchor, axis=1)))
        if d > config.max_generic_distance_m:
            return fit, (f"the {fit.method} centre lies {1e3 * d:.0f} mm from the generic skeleton's joint "
                         f"(over {1e3 * config.max_generic_distance_m:.0f} mm: mislabelled markers?)")
    return fit, ""


def joint_centres(traj, *, config: JointCentresConfig = JointCentresConfig(), observer=None) -> JointCentresResult:
    """Joint centres of the 14-joint skeleton from marker trajectories.

    Parameters
    ----------
    traj : MarkerTrajectories
        Labelled markers (T frames, M markers, metres, NaN where missing);
        labels that no marker set or rule knows (e.g. ``M000``) or
        ``config.marker_set == "none"`` take the path without labels.
    config : JointCentresConfig
    observer : Observer, optional
        Receives ``text`` reports (one per joint) and, without labels, the subsets.

    Returns
    -------
    JointCentresResult

    Raises
    ------
    InputError
        Fewer than three frames with two markers seen; a marker set named in
        ``config`` of which the labels hold fewer than three markers.
    """
    obs = as_observer(observer)
    pos = np.asarray(traj.positions, dtype=float)
    if pos.ndim != 3 or pos.shape[0] < 3 or pos.shape[1] < 2:
        raise InputError(f"{traj.source}: positions", "at least 3 frames of at least 2 markers", f"{pos.shape}")
    n_seen = int(np.sum(np.isfinite(pos).all(axis=-1).sum(axis=1) >= 2))
    if n_seen < 3:
        raise InputError(f"{traj.source}: positions", "at least 3 frames with at least 2 markers seen",
                         f"{n_seen} such frames of {pos.shape[0]} (markers missing, NaN, in the others)")
    mset = _choose_marker_set(traj.labels, config.marker_set)
    if mset is not None and config.marker_set != "auto":
        known = [lab for lab in mset.labels if lab in traj.labels]
        if len(known) < 3:
            raise InputError(f"{traj.source}: labels (marker set {mset.name!r} asked for)",
                             f"at least 3 of the marker set's labels (e.g. {list(mset.labels[:4])})",
                             f"{len(known)} of them among {list(traj.labels[:6])}"
                             f"{' ...' if traj.n_markers > 6 else ''}")
    groups = {} if config.marker_set == "none" else _segment_groups(traj, mset)
    if sum(1 for g in groups.values() if g) < 2:
        return _unlabelled(traj, config, obs)
    return _labelled(traj, groups, mset, config, obs)


def _labelled(traj, groups, mset, config, obs) -> JointCentresResult:
    pos = traj.positions
    t = pos.shape[0]
    messages = []
    never = np.flatnonzero(~np.isfinite(pos).all(axis=-1).any(axis=0))
    if never.size:
        messages.append(f"markers {[traj.labels[i] for i in never]} are missing in every frame; left out of "
                        "the fits")
        groups = {k: [i for i in v if i not in set(never.tolist())] for k, v in groups.items()}
    short = min(10, t)  # a trial of fewer frames than distance_std's default: judge pairs on all of them
    std, _ = _r.distance_std(pos, min_frames=short)
    bad = _r.check_segments(pos, groups, tolerance_m=config.segment_tolerance_m, min_frames=short)
    for seg, idx in bad.items():
        messages.append(f"{seg}: markers {[traj.labels[i] for i in idx]} do not move rigidly with the "
                        f"others of the segment (distance std over {1e3 * config.segment_tolerance_m:.0f} mm); "
                        "left out of the fits")
        groups[seg] = [i for i in groups[seg] if i not in idx]
    ext = _extend(groups, std, config.rigid_tolerance_m)
    # generic skeleton: the marker set's template scaled to the performer, else anatomical rules
    height = float(config.height_m) if config.height_m > 0 else 0.0
    generic = np.full((t, 14, 3), np.nan)
    # trajectories labelled against the marker set's own template (a synthetic capture, traj.segments
    # given) trust the template first; a file from elsewhere trusts the anatomical landmark rules first
    template_first = traj.segments is not None
    if height <= 0 and not template_first:
        height = _s.stature_from_legs(_s.anatomical_joints(traj.labels, pos))
    if mset is not None:
        labels = traj.labels
        if height <= 0:
            height = _s.fit_stature(pos, ext, mset, labels)
        from toolkit.anthropometry.proportions import BodyProportions
        tm, tj, _ = _s.template_frames(mset, BodyProportions.from_height(height), labels)
        generic, _ = _s.template_joints(pos, ext, tm, tj)
    anat = _s.anatomical_joints(traj.labels, pos, height_m=height if height > 0 else 1.75,
                                measurements=traj.measurements)
    has_t = np.isfinite(generic).all(axis=-1).any(axis=0)
    has_a = np.isfinite(anat).all(axis=-1).any(axis=0)
    use_t = has_t & (template_first | ~has_a)
    source = np.where(use_t, "template", "anatomical")
    first, second = np.where(use_t[None, :, None], generic, anat), np.where(use_t[None, :, None], anat, generic)
    generic = np.where(np.isfinite(first), first, second)  # a frame the first estimate misses: the other

    joints = generic.copy()
    method = [str(s) if np.isfinite(generic[:, j]).any() else "none" for j, s in enumerate(source)]
    residual = np.full(14, np.nan)
    rom = np.full(14, np.nan)
    fits = {}
    functional = {}
    for name, parent, child, kind in FUNCTIONAL_JOINTS:
        j = _s.J14[name]
        p_idx, c_idx = ext.get(parent, []), ext.get(child, [])
        if not p_idx:
            continue
        ppos = pos[:, p_idx]
        if len(p_idx) < 3 and PROXIMAL.get(parent) in functional:
            ppos = np.concatenate([ppos, functional[PROXIMAL[parent]][:, None]], axis=1)
        fit, why = _fit_joint(kind, ppos, pos[:, c_idx], generic[:, j], config, trusted=source[j] == "template",
                              n_own=len(groups.get(child, ())))
        if fit is not None:
            rom[j] = fit.rom_deg[0]
        if fit is None or why:
            messages.append(f"{name}: generic skeleton's joint kept, {why}")
            obs.report("text", text=f"{name}: generic ({why})", name="markers/joints", level="WARN")
            continue
        fits[name] = fit
        residual[j] = fit.residual_m
        functional[name] = fit.centre
        ok = np.isfinite(fit.centre).all(axis=1)
        joints[ok, j] = fit.centre[ok]
        method[j] = fit.method
        obs.report("text", text=f"{name}: {fit.method}, residual {1e3 * fit.residual_m:.1f} mm, "
                   f"range of motion {fit.rom_deg[0]:.0f} deg", name="markers/joints")
    if not fits:
        messages.append("no functional centre: the trial shows too little movement (functional centres need "
                        "movement); the joints are the scaled generic skeleton's")
    if height <= 0:
        from toolkit.markers.marker_sets import proportions_from_joints
        filled = np.where(np.isfinite(joints), joints, 0.0)
        height = proportions_from_joints(filled).height if np.isfinite(joints).all() else 1.75
    lengths = _s.bone_lengths(joints)
    gl = _s.generic_lengths(height)
    lengths = {k: (v if np.isfinite(v) else gl[k]) for k, v in lengths.items()}
    return JointCentresResult(names=SKELETON_14.joint_names, joints=joints, method=tuple(method),
                              residual_m=residual, rom_deg=rom, fits=fits,
                              subsets={k: tuple(v) for k, v in ext.items()}, height_m=float(height),
                              lengths=lengths, messages=messages, labelled=True,
                              marker_set=mset.name if mset is not None else "labels", generic=generic)


def _unlabelled(traj, config, obs) -> JointCentresResult:
    pos = traj.positions
    t = pos.shape[0]
    rs = _r.find_rigid_subsets(pos, threshold_m=config.subset_threshold_m)
    subsets = {f"S{k}": s for k, s in enumerate(rs.subsets)}
    motions = {k: _motion(pos[:, list(s)]) for k, s in subsets.items()}
    cents = {k: np.nanmean(pos[:, list(s)], axis=1) for k, s in subsets.items()}
    cands = []
    names = list(subsets)
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            ma, mb = motions[names[a]], motions[names[b]]
            if ma is None or mb is None:
                continue
            try:
                fit = _c.score(ma[0], ma[1], mb[0], mb[1])
            except InputError:
                continue
            with _r._quiet():
                da = np.nanmedian(np.linalg.norm(fit.centre - cents[names[a]], axis=1))
                db = np.nanmedian(np.linalg.norm(fit.centre - cents[names[b]], axis=1))
            if fit.residual_m <= config.max_joint_residual_m and max(da, db) < 0.4 \
                    and fit.rom_deg[0] >= config.min_rom_deg:
                if fit.rom_deg[1] < config.planar_ratio * fit.rom_deg[0]:
                    anchor = 0.5 * (cents[names[a]] + cents[names[b]])
                    fit = _c.sara(ma[0], ma[1], mb[0], mb[1], anchor=anchor)
                cands.append((fit.residual_m, names[a], names[b], fit))
    # markers in no subset (a segment with one or two markers, e.g. a forearm): grouped by the same
    # clustering, each group's centre of rotation in a subset's frame by a sphere fit
    small = _small_groups(pos, rs, config.subset_threshold_m)
    for g, idx in small.items():
        subsets[g] = idx
        with _r._quiet():
            gc = np.nanmean(pos[:, list(idx)], axis=1)
        for a in names:
            if motions[a] is None:
                continue
            try:
                fit = _c.sphere_centre(motions[a][0], motions[a][1], pos[:, list(idx)])
            except InputError:
                continue
            with _r._quiet():
                da = np.nanmedian(np.linalg.norm(fit.centre - cents[a], axis=1))
                dg = np.nanmedian(np.linalg.norm(fit.centre - gc, axis=1))
            if fit.residual_m <= 0.5 * config.max_joint_residual_m and max(da, dg) < 0.4 \
                    and fit.rom_deg[0] >= config.min_rom_deg and dg > 0.02:
                cands.append((fit.residual_m, a, g, fit))
    names = list(subsets)
    # a spanning forest of the best joints (a body's subsets form a tree)
    parent = {n: n for n in names}

    def root(n):
        while parent[n] != n:
            n = parent[n]
        return n

    fits = {}
    for _res, a, b, fit in sorted(cands, key=lambda c: c[0]):
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[rb] = ra
            fits[f"{a}-{b}"] = fit
            obs.report("text", text=f"{a}-{b}: {fit.method}, residual {1e3 * fit.residual_m:.1f} mm, "
                       f"range of motion {fit.rom_deg[0]:.0f} deg", name="markers/joints")
    messages = [f"no labels: {len(rs.subsets)} rigid subsets and {len(fits)} centres of rotation; "
                "the 14-joint skeleton needs labelled markers"]
    if small:
        messages.append("markers in groups too small for a rigid motion (centres by sphere fits): "
                        + "; ".join(f"{g}: {[traj.labels[i] for i in idx]}" for g, idx in small.items()))
    return JointCentresResult(names=SKELETON_14.joint_names, joints=np.full((t, 14, 3), np.nan),
                              method=("none",) * 14, residual_m=np.full(14, np.nan), rom_deg=np.full(14, np.nan),
                              fits=fits, subsets=subsets, height_m=float("nan"), lengths={},
                              messages=messages, labelled=False, marker_set="none")


def _small_groups(pos, rs, threshold_m) -> dict:
    """The markers no rigid subset holds, clustered by their distance std into groups of one or two."""
    left = list(rs.leftover)
    if not left:
        return {}
    if len(left) == 1:
        return {"G0": (left[0],)}
    from sklearn.cluster import AgglomerativeClustering

    std = rs.std[np.ix_(left, left)]
    d = np.where(np.isfinite(std), std, 1e3)
    lab = AgglomerativeClustering(n_clusters=None, metric="precomputed", linkage="average",
                                  distance_threshold=threshold_m).fit(d).labels_
    return {f"G{k}": tuple(left[i] for i in np.flatnonzero(lab == u)) for k, u in enumerate(np.unique(lab))}


def trajectories_from_c3d(path, *, require_labels: bool = False):
    """The 3D points of a C3D file as :class:`~toolkit.markers.trajectories.MarkerTrajectories`.

    Parameters
    ----------
    path : str or PathLike
    require_labels : bool
        See :func:`toolkit.io.c3d.read_c3d`.

    Returns
    -------
    MarkerTrajectories
        State ``FROM_FILE`` where a sample is present, ``MISSING`` where not.
    """
    from toolkit.io.c3d import read_c3d
    from toolkit.markers.trajectories import FROM_FILE, MISSING, MarkerTrajectories

    pts = read_c3d(path, require_labels=require_labels)
    seen = np.isfinite(pts.positions).all(axis=-1)
    pos = np.where(seen[..., None], pts.positions, np.nan)
    return MarkerTrajectories(pts.labels, pos, np.where(seen, FROM_FILE, MISSING).astype(np.int8), pts.fps,
                              None, str(path), dict(pts.measurements))
