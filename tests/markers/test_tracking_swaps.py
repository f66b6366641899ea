"""Tracking: swaps whose other half is unmeasured, one-mate swaps, fast feet (issue 17, rom seed 91, walks at 50 fps)."""

from __future__ import annotations

import numpy as np

from tests.markers.test_labelling import blobs_of, ring_rig, track
from toolkit.markers.reconstruct import RigGeometry, reconstruct_frame
from toolkit.markers.track import TrackConfig, Tracker, TrackState
from toolkit.markers.trajectories import BRIDGED, MISSING, TRINOCULAR

#: Reconstruction error without noise, metres.
EXACT_M = 1e-6


def hand_leaving_the_thigh(n_frames=36, leave=12, gap_m=0.015, step_m=0.01):
    """The right thigh (``RTHI``, ``RKNE``) at rest with the hand (``RFIN`` and the forearm's ``RFRM``,
    ``RWRA``, ``RWRB``) resting ``gap_m`` from ``RTHI``; from frame ``leave`` the hand moves away
    ``step_m`` per frame.  (T, 6, 3) metres and the segments."""
    f = np.arange(n_frames)
    thigh = np.array([[0.0, 0.0, 0.8], [0.01, 0.02, 0.42]])
    hand = np.array([[0.0, gap_m, 0.8], [0.05, 0.06, 1.1], [0.02, 0.07, 0.9], [0.07, 0.09, 0.92]])
    away = step_m * np.maximum(f - leave, 0)
    X = np.concatenate([np.broadcast_to(thigh, (n_frames, 2, 3)),
                        hand[None] + away[:, None, None] * np.array([0.0, 1.0, 0.3])], axis=1)
    return X, ("r_thigh", "r_thigh", "r_hand", "r_forearm", "r_forearm", "r_forearm")


def tracker_with_fin_on_the_thigh(X, segments, *, hidden=lambda f: (2,) if f >= 6 else (), wrong_from=6, wrong_to=10,
                                  config=TrackConfig()):
    """A tracker whose frames ``0..wrong_to`` are labelled as the tracker of rom seed 91 left them: right up to
    ``wrong_from``, then ``RFIN``'s label on ``RTHI``'s marker (the finger unseen: ``hidden(f)``, the markers no
    camera sees in frame ``f``) and ``RTHI``'s label bridged 12 mm off its marker.  Returns the tracker, its
    state and the frame order."""
    rig = ring_rig()
    rng = np.random.default_rng(3)
    geom = RigGeometry.of(rig)
    blobs = [blobs_of(rig, X[f], rng, hidden={(c, i) for c in range(len(rig)) for i in hidden(f)})
             for f in range(len(X))]
    recon = [reconstruct_frame(geom, b) for b in blobs]
    st = TrackState.empty(len(X), segments)

    def label(f, where):  # label i -> the reconstruction nearest to X[f, where[i]]
        d = np.linalg.norm(recon[f].points[:, None] - X[f][where][None], axis=2)
        st.point[f] = np.argmin(d, axis=0)
        st.positions[f] = recon[f].points[st.point[f]]
        st.state[f] = TRINOCULAR

    label(0, [0, 1, 2, 3, 4, 5])
    tracker = Tracker(geom, lambda f: blobs[f], lambda f: recon[f], st, config)  # references from frame 0
    for f in range(1, wrong_to + 1):
        label(f, [0, 1, 2, 3, 4, 5] if f < wrong_from else [0, 1, 0, 3, 4, 5])
        if f >= wrong_from:
            st.positions[f, 0], st.state[f, 0], st.point[f, 0] = X[f, 0] + [0.012, 0.0, 0.0], BRIDGED, -1
    order = list(range(len(X)))
    return tracker, st, order


def test_a_measured_label_on_another_segments_marker_gives_it_back_when_the_hand_leaves():
    """Rom seed 91: the finger unseen beside the thigh, its label on the thigh marker, the thigh's bridged."""
    X, segments = hand_leaving_the_thigh()
    results = {}
    for name, cfg in (("off", TrackConfig(cross_min_m=np.inf)), ("on", TrackConfig())):
        tracker, st, order = tracker_with_fin_on_the_thigh(X, segments, config=cfg)
        for k in range(11, len(order)):
            tracker.step(order, k)
        results[name] = st
    off, on = results["off"], results["on"]
    # without the check the finger's label follows the thigh marker away from its hand to the end
    assert np.linalg.norm(off.positions[11:, 2] - X[11:, 0], axis=1).max() < EXACT_M
    # with it: the thigh's label gets its marker back, down to the first frame the finger's label took it
    assert np.all(on.state[6:, 0] == TRINOCULAR)
    assert np.linalg.norm(on.positions[6:, 0] - X[6:, 0], axis=1).max() < EXACT_M
    # the finger's label never on the thigh marker again: missing, or bridged with its forearm near its marker
    fin = on.state[6:, 2]
    assert set(np.unique(fin)) <= {MISSING, BRIDGED}
    bridged = np.flatnonzero(on.state[:, 2] == BRIDGED)
    assert bridged.size > 10  # carried by the forearm from its last measurement (frame 5)
    assert np.linalg.norm(on.positions[bridged, 2] - X[bridged, 2], axis=1).max() < 1e-3
    assert all(np.unique(row[row >= 0]).size == (row >= 0).sum() for row in on.point)


def test_a_bridge_carried_from_a_place_its_mates_refuse_is_not_made():
    """A label last measured on another segment's marker (the hand 5 cm away by then) is not carried on from
    there: bridged, it would sit 5 cm off its forearm, where no finger can be."""
    X, segments = hand_leaving_the_thigh(leave=6)
    hidden = lambda f: (2,) if f < 12 and f >= 6 else (0, 2) if f >= 12 else ()  # noqa: E731
    results = {}
    for name, cfg in (("off", TrackConfig(cross_min_m=np.inf)), ("on", TrackConfig())):
        tracker, st, order = tracker_with_fin_on_the_thigh(X, segments, hidden=hidden, wrong_from=11, wrong_to=11,
                                                           config=cfg)
        assert tracker.off_mates(11, 2, st.positions[11, 2])[0] > 0.03  # frame 11: the label 5 cm off its hand
        tracker.step(order, 12)
        results[name] = st
    off, on = results["off"], results["on"]
    assert off.state[12, 2] == BRIDGED and np.linalg.norm(off.positions[12, 2] - X[12, 2]) > 0.03
    assert on.state[12, 2] == MISSING
    assert np.array_equal(on.state[12, 3:], off.state[12, 3:])  # the forearm itself tracked the same


def swinging_leg(n_frames=20, step_m=0.08):
    """A shank and a foot cluster (4 markers each) swinging forwards ``step_m`` per frame from frame 0 (a
    walk at 50 fps), beside a standing leg's 4 markers 15 cm away.  (T, 12, 3) metres and the segments."""
    f = np.arange(n_frames)
    cluster = np.array([[0.0, 0.0, 0.0], [0.05, 0.01, 0.0], [0.0, 0.05, 0.03], [0.04, 0.06, -0.03]])
    shank, foot = cluster + [0.0, 0.15, 0.4], cluster[[1, 0, 3, 2]] + [0.05, 0.15, 0.05]
    standing = cluster + [0.0, -0.0, 0.3]
    x = (step_m * f)[:, None, None] * np.array([1.0, 0.0, 0.0])
    X = np.concatenate([np.broadcast_to(standing, (n_frames, 4, 3)), shank[None] + x, foot[None] + 1.2 * x], axis=1)
    return X, ("r_shank",) * 4 + ("l_shank",) * 4 + ("l_foot",) * 4


def test_a_leg_swinging_8_cm_per_frame_is_tracked_from_the_first_frame():
    """A walk at 50 fps: no marker has a velocity in the first step; gated as a tracked one it is lost."""
    X, segments = swinging_leg()
    rig = ring_rig()
    narrow = track(rig, X, config=TrackConfig(first_gate_m=0.06), segments=segments)
    wide = track(rig, X, segments=segments)
    assert np.mean(np.linalg.norm(narrow.positions[:, 4:] - X[:, 4:], axis=2) < 1e-3) < 0.5  # lost or swapped
    assert np.linalg.norm(wide.positions - X, axis=2).max() < EXACT_M
    assert np.all(wide.state == TRINOCULAR)


def test_a_marker_identification_missed_is_found_near_its_hint():
    """A hand's marker unseen in the labelled frame, the template's hint 12 cm off (walk plug-in-gait 101)."""
    X, segments = hand_leaving_the_thigh(n_frames=20, leave=0)
    X, segments = X[:, 2:], segments[2:]  # the hand alone: RFIN, RFRM, RWRA, RWRB
    rig = ring_rig()
    rng = np.random.default_rng(4)
    geom = RigGeometry.of(rig)
    blobs = [blobs_of(rig, X[f], rng, ghosts=3, hidden={(c, 0) for c in range(len(rig))} if f == 0 else set())
             for f in range(len(X))]
    recon = [reconstruct_frame(geom, b) for b in blobs]
    results = {}
    for name, cfg in (("off", TrackConfig(hint_reach_m=0.0)), ("on", TrackConfig())):
        st = TrackState.empty(len(X), segments)
        d = np.linalg.norm(recon[0].points[:, None] - X[0, 1:][None], axis=2)
        st.point[0, 1:] = np.argmin(d, axis=0)
        st.positions[0, 1:] = recon[0].points[st.point[0, 1:]]
        st.state[0, 1:] = TRINOCULAR
        st.hint[0], st.hint_frame[0] = X[0, 0] + [0.08, -0.08, 0.04], 0
        Tracker(geom, lambda f: blobs[f], lambda f: recon[f], st, cfg).run(list(range(len(X))))
        results[name] = st
    assert np.all(results["off"].state[:, 0] == MISSING)  # the hint is 12 cm off: beyond every gate
    on = results["on"]
    assert np.all(on.state[1:, 0] == TRINOCULAR)
    assert np.linalg.norm(on.positions[1:] - X[1:], axis=2).max() < EXACT_M


def knees_brushing(n_frames=45, touch=14, gap_m=0.004, step_m=0.01):
    """Two thighs of Plug-in Gait (``THI``, ``KNE`` each: one rigid mate per marker): the left moves 10 mm
    per frame along x until frame ``touch``, where its ``KNE`` comes within ``gap_m`` of the resting right
    ``KNE``, and stops; then the right thigh moves on as the left did, rising."""
    f = np.arange(n_frames)
    left = np.array([[0.0, 0.0, 0.8], [0.0, 0.0, 0.45]])  # LTHI, LKNE
    right = np.array([[0.02, gap_m + 0.12, 0.78], [0.0, gap_m, 0.45]])  # RTHI, RKNE
    x_left = step_m * (np.minimum(f, touch) - touch)
    x_right = step_m * np.maximum(f - touch, 0)
    X = np.concatenate([left[None] + x_left[:, None, None] * [1, 0, 0],
                        right[None] + x_right[:, None, None] * np.array([1, 0, 0.5])], axis=1)
    return X, ("l_thigh", "l_thigh", "r_thigh", "r_thigh")


def test_a_swap_of_two_one_mate_labels_is_undone_once_it_persists():
    X, segments = knees_brushing()
    rig = ring_rig()
    never = track(rig, X, config=TrackConfig(cross_persist_frames=10 ** 6), segments=segments)  # one-mate pairs
    on = track(rig, X, segments=segments)                                                         # never checked
    # the window gives the left knee's label to the right knee moving on: LKNE and RKNE swapped
    assert np.allclose(never.positions[-1, [1, 3]], X[-1, [3, 1]], atol=EXACT_M)
    err = np.linalg.norm(on.positions - X, axis=2)
    assert err[:15].max() < 5e-3
    assert err[-10:].max() < EXACT_M  # swapped back
    swapped = np.flatnonzero(np.linalg.norm(on.positions[:, 1] - X[:, 3], axis=1) < 1e-3)
    assert swapped.size == 0 or swapped.max() < 15 + 2 * TrackConfig().cross_persist_frames
    assert all(np.unique(row).size == 4 for row in on.point)


def still_arm(n_frames=30):
    """A still left arm: the upper arm's ``UPA``, ``ELB`` and the forearm's ``FRM`` within 1 mm of one line,
    the wrist bar's ``WRA``, ``WRB`` 27 cm along it, 7 cm apart across it (rom seed 112).  (T, 5, 3) metres
    and the segments."""
    P = np.array([[-0.15, 0.0, 1.2], [0.0, 0.001, 1.2], [0.13, 0.0, 1.2], [0.27, 0.035, 1.22], [0.27, -0.035, 1.18]])
    return np.broadcast_to(P, (n_frames, 5, 3)).copy(), ("l_upperarm",) * 2 + ("l_forearm",) * 3


def test_wrist_markers_lost_together_are_not_carried_by_nearly_collinear_mates():
    """Rom seed 112: both wrist markers unseen for 10 frames, the forearm's one other marker and the upper
    arm's two carry them; 4 mm of noise turns the three nearly collinear mates anywhere about their line,
    the carried wrist 3-8 cm off, and ``WRB`` seen again first takes ``WRA``'s label.  The rotation they
    leave undetermined (:meth:`Tracker.rigid_carry`) must not carry the wrist."""
    X, segments = still_arm()
    rig = ring_rig()
    geom = RigGeometry.of(rig)
    hidden = lambda f: (3, 4) if 5 <= f < 15 else (3,) if 15 <= f < 17 else ()  # noqa: E731
    wrong = {}
    for name, cfg in (("off", TrackConfig(carry_noise_m=0.0)), ("on", TrackConfig())):
        wrong[name] = []
        for seed in range(6):
            rng = np.random.default_rng(seed)
            blobs = [blobs_of(rig, X[f], rng, noise=1.0, hidden={(c, i) for c in range(len(rig)) for i in hidden(f)})
                     for f in range(len(X))]
            recon = [reconstruct_frame(geom, b) for b in blobs]
            st = TrackState.empty(len(X), segments)
            st.point[0] = np.argmin(np.linalg.norm(recon[0].points[:, None] - X[0][None], axis=2), axis=0)
            st.positions[0], st.state[0] = recon[0].points[st.point[0]], TRINOCULAR
            tracker = Tracker(geom, lambda f: blobs[f], lambda f: recon[f], st, cfg)
            tracker.run(list(range(len(X))))
            wrong[name].append(int(np.sum(np.linalg.norm(st.positions[:, 3:] - X[:, 3:], axis=2) > 0.02)))
            if name == "on":
                assert np.all(st.state[17:, 3:] == TRINOCULAR)
                a = st.positions[0, :3]
                assert not tracker.rigid_carry(a, a, X[0, 3], np.inf)[1]  # 27 cm from mates 1 mm across
    assert max(wrong["off"]) > 10  # a swap of the wrist labels to the end
    assert wrong["on"] == [0] * 6
