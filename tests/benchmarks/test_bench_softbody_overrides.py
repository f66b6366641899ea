"""The soft-body benchmark's ``--set`` overrides of the run config."""

import pytest

from benchmarks.bench_softbody import parse_overrides


def test_overrides_parse_sections_fields_and_values():
    got = parse_overrides(["track.posture_weight=0.5", "fit.loss='cauchy'", "init_posture_weight=0",
                           "refine.enabled=True", "fit.max_nfev=12"])
    assert got == {"track": {"posture_weight": 0.5}, "fit": {"loss": "cauchy", "max_nfev": 12},
                   "": {"init_posture_weight": 0}, "refine": {"enabled": True}}
    assert parse_overrides([]) == {}


@pytest.mark.parametrize("item, message", [
    ("track.posture_weight", "expected"),
    ("nosuch.field=1", "no config section 'nosuch'"),
    ("track.nosuch=1", "TrackConfig has no field 'nosuch'"),
    ("nosuch=1", "SoftBodyRunConfig has no field 'nosuch'"),
    ("track=1", "is a section"),
])
def test_bad_overrides_are_named(item, message):
    with pytest.raises(SystemExit, match=message):
        parse_overrides([item])
