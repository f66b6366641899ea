"""The soft-body benchmark's ``--set`` overrides of the run config (read as a ``--config`` file is)."""

import pytest

from benchmarks.bench_softbody import apply_overrides, parse_overrides
from toolkit.pipeline.soft_body import SoftBodyRunConfig
from toolkit.softbody import TrackConfig


def test_overrides_set_only_the_fields_given():
    got = parse_overrides(["track.posture_weight=0.5", "fit.loss='cauchy'", "init_posture_weight=0",
                           "refine.enabled=true", "fit.max_nfev=12"])
    assert got == {"track": {"posture_weight": 0.5}, "fit": {"loss": "cauchy", "max_nfev": 12},
                   "init_posture_weight": 0, "refine": {"enabled": True}}
    base = SoftBodyRunConfig(recording=False, track=TrackConfig(silhouette_weight=0.0))
    cfg = apply_overrides(base, got)
    assert cfg.track.posture_weight == 0.5 and cfg.track.silhouette_weight == 0.0  # the others kept
    assert (cfg.fit.loss, cfg.fit.max_nfev, cfg.refine.enabled) == ("cauchy", 12, True)
    assert cfg.init_posture_weight == 0 and cfg.recording is False
    assert parse_overrides([]) == {} and apply_overrides(base, {}) is base


@pytest.mark.parametrize("item, message", [
    ("track.posture_weight", "expected"),
    ("fit.loss=cauchy", "strings quoted"),
    ("nosuch.field=1", "nosuch"),
    ("track.nosuch=1", "TrackConfig"),
    ("track.posture_weight=-1", "posture_weight"),
])
def test_bad_overrides_are_named(item, message):
    with pytest.raises(SystemExit, match=message):
        parse_overrides([item])
