"""Report kinds are declared once; the recording fake rejects what the declarations do not allow."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.observe import (
    COMMON_FIELDS,
    REPORT_KINDS,
    MultiObserver,
    PrefixedObserver,
    RecordingObserver,
    ReportKind,
    check_report,
)

REPO = Path(__file__).resolve().parents[2]


def test_recording_observer_keeps_declared_reports():
    obs = RecordingObserver()
    obs.report("joints2d", camera="cam_0", joints=np.zeros((14, 2)), name="stage1/chosen", frame=3)
    obs.report("scalar", name="multiview/cost_mm", value=1.5, static=True)
    assert obs.kinds == {"joints2d", "scalar"}
    assert obs.of_kind("joints2d")[0]["frame"] == 3


@pytest.mark.parametrize("kind, data, found", [
    ("joint3d", {"joints": np.zeros((14, 3))}, "'joint3d'"),                            # misspelt kind
    ("joints3d", {"joints": np.zeros((14, 3)), "skelton": None}, "unknown ['skelton']"),  # misspelt field
    ("joints3d", {"joint": np.zeros((14, 3))}, "unknown ['joint']"),
    ("joints2d", {"joints": np.zeros((14, 2)), "name": "x"}, "missing ['camera']"),     # missing field
    ("scalar", {"name": "x", "value": None}, "missing ['value']"),
    ("depth_energy", {"stage": "track", "iteration": 0, "total": 1.0, "surface": 1.0}, "unknown ['surface']"),
])
def test_recording_observer_rejects_what_is_not_declared(kind, data, found):
    obs = RecordingObserver()
    with pytest.raises(InputError) as e:
        obs.report(kind, **data)
    assert found in e.value.found and e.value.where.startswith("report")
    assert obs.reports == []


def test_forwarding_observers_reach_the_check():
    rec = RecordingObserver()
    with pytest.raises(InputError):
        MultiObserver(rec).report("scalar", name="x", valu=1.0)
    with pytest.raises(InputError):
        PrefixedObserver(rec, "person_0").report("text", txt="hello")


def test_declarations_are_consistent():
    for name, decl in REPORT_KINDS.items():
        assert isinstance(decl, ReportKind) and decl.name == name and decl.doc
        assert decl.required, name
        assert set(COMMON_FIELDS) <= decl.fields
        assert all(isinstance(v, str) and v for v in {**decl.required, **decl.optional}.values())
    assert {"depth_energy", "depth_move", "depth_radial"} <= set(REPORT_KINDS)
    with pytest.raises(InputError):
        ReportKind("x", "both", {"a": "int"}, {"a": "int"})
    check_report("image", {"camera": "c", "image": np.zeros((2, 2, 3), np.uint8)})


def _report_calls():
    """Every ``<x>.report("<kind>", field=...)`` in toolkit/, recipes/ and benchmarks/: kind, fields, place."""
    for folder in ("toolkit", "recipes", "benchmarks"):
        for path in sorted((REPO / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                        and node.func.attr == "report" and node.args and isinstance(node.args[0], ast.Constant)):
                    fields = {kw.arg for kw in node.keywords if kw.arg is not None}
                    yield node.args[0].value, fields, f"{path.relative_to(REPO)}:{node.lineno}"


def test_every_report_in_the_code_is_declared():
    """Reports on paths no test drives are checked too: their kind and literal fields against the declarations."""
    calls = list(_report_calls())
    assert len(calls) > 100, "the scan found few report calls: it is broken"
    bad = []
    for kind, fields, where in calls:
        decl = REPORT_KINDS.get(kind)
        if decl is None:
            bad.append(f"{where}: undeclared kind {kind!r}")
        elif fields - decl.fields:
            bad.append(f"{where}: {kind!r} fields {sorted(fields - decl.fields)} not declared")
    assert not bad, "\n".join(bad)
