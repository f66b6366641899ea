"""Points not taken for the subject's count as another body's only in pieces as long as a person
(:func:`toolkit.softbody.confidence.other_bodies`): a limb the model left is no other body."""

import numpy as np

from toolkit.softbody.confidence import ConfidenceConfig, other_bodies


def _segment(a, b, n, rng):
    return np.linspace(a, b, n) + rng.normal(0, 0.005, (n, 3))


def test_a_person_sized_piece_is_another_body_and_an_arm_is_not():
    rng = np.random.default_rng(0)
    person = _segment([1.0, 0.0, 0.0], [1.0, 0.0, 1.7], 120, rng)      # 1.7 m tall, 1.5 cm apart
    arm = _segment([0.0, 0.0, 1.5], [0.0, 0.2, 2.1], 40, rng)           # 0.63 m, apart from the person
    pts = np.vstack([person, arm])
    kept = other_bodies(pts, ConfidenceConfig().other_body_extent)
    assert len(kept) == len(person)
    np.testing.assert_allclose(np.sort(kept[:, 2]), np.sort(person[:, 2]))
    assert len(other_bodies(pts, 0.0)) == len(pts)
    assert other_bodies(np.zeros((0, 3)), 1.0).shape == (0, 3)
