"""The run layer: config identity, TOML configs (unknown keys rejected), frame records, run folders."""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import pytest

from toolkit.errors import InputError
from toolkit.pipeline.free_viewpoint import FreeViewpointRunConfig
from toolkit.pipeline.run import (FrameRecords, config_from_dict, config_identity, load_config, open_run)


@dataclass(frozen=True)
class Inner:
    step_m: float = 0.01
    sizes: tuple = (1, 2)


@dataclass(frozen=True)
class Outer:
    inner: Inner = field(default_factory=Inner)
    path: Path | None = None
    name: str = "a"
    progress: bool = True


def test_identity_holds_every_field_nested_and_json_safe(tmp_path):
    ident = config_identity(Outer(path=tmp_path / "x"), exclude=("progress",))
    assert ident == {"inner": {"step_m": 0.01, "sizes": [1, 2]}, "path": str((tmp_path / "x").resolve()),
                     "name": "a"}
    json.dumps(ident)
    # a changed nested option changes the identity: no hand-kept dict can forget one
    assert config_identity(Outer(inner=Inner(step_m=0.02))) != config_identity(Outer())
    with pytest.raises(InputError, match="progres"):
        config_identity(Outer(), exclude=("progres",))


def test_config_from_dict_nested_tables_paths_tuples():
    c = config_from_dict(Outer, {"inner": {"step_m": 0.5, "sizes": [3]}, "path": "a/b", "name": "z"})
    assert c == Outer(inner=Inner(0.5, (3,)), path=Path("a/b"), name="z")


def test_unknown_keys_are_rejected_with_where_and_the_known_ones():
    with pytest.raises(InputError) as e:
        config_from_dict(Outer, {"inner": {"step": 0.5}}, where="f.toml")
    assert "f.toml: inner.step" in str(e.value) and "step_m" in str(e.value)  # the key at fault, the known ones
    with pytest.raises(InputError, match="a table of Inner"):
        config_from_dict(Outer, {"inner": 3}, where="f.toml")


def test_load_config_file_then_overrides(tmp_path):
    p = tmp_path / "run.toml"
    p.write_text('foreground = "chroma"\nmax_frames = 3\n[frame]\noptimize = false\n[frame.optimize_config]\n'
                 'max_sweeps = 1\n')
    c = load_config(FreeViewpointRunConfig, p, max_frames=5, hold_out=None)
    assert c.foreground == "chroma" and c.max_frames == 5 and not c.frame.optimize
    assert c.frame.optimize_config.max_sweeps == 1
    p.write_text('foregroud = "chroma"\n')
    with pytest.raises(InputError) as e:
        load_config(FreeViewpointRunConfig, p)
    assert str(p) in str(e.value) and "foregroud" in str(e.value)
    p.write_text('foreground = "paint"\n')
    with pytest.raises(InputError, match="foreground"):
        load_config(FreeViewpointRunConfig, p)
    with pytest.raises(InputError, match="no such file"):
        load_config(FreeViewpointRunConfig, tmp_path / "none.toml")


def test_frame_records_resume_and_unreadable(tmp_path):
    r = FrameRecords(tmp_path, 3)
    assert r.todo() == [0, 1, 2]
    r.write(1, {"frame": 1, "x": float("nan")})
    assert r.done() == {1} and r.todo() == [0, 2]
    assert r.read_all()[0]["frame"] == 1
    r.path(2).write_text("{not json")
    with pytest.raises(InputError, match="000002.json"):
        r.read_all()


def test_open_run_identity_from_config_names_what_differs(tmp_path):
    ds = tmp_path / "ds"
    (ds / "videos").mkdir(parents=True)
    (ds / "calibration.toml").write_text("x = 1\n")
    out = tmp_path / "out"
    c = FreeViewpointRunConfig()
    f = open_run(out, "free_viewpoint", ds, c, 2, exclude=c.RUNTIME, log=None)
    assert not f.resumed and f.recording is not None and f.records.todo() == [0, 1]
    # runtime options do not change the identity; a nested algorithm option does, and is named
    assert open_run(out, "free_viewpoint", ds, replace(c, progress=False, max_frames=1), 2, exclude=c.RUNTIME,
                    log=None).resumed
    other = replace(c, frame=replace(c.frame, optimize=False))
    with pytest.raises(InputError, match=r"config\.frame\.optimize"):
        open_run(out, "free_viewpoint", ds, other, 2, exclude=c.RUNTIME, log=None)


def test_config_from_dict_tuples_of_tables_and_nested_arrays():
    from toolkit.silhouettes import Stage1Config

    # nested configs, a tuple of (camera, px) pairs, a tuple of joint-limit tables
    c = Stage1Config().with_refined_cameras(["a", "b"])
    back = config_from_dict(Stage1Config, json.loads(json.dumps(config_identity(c))))  # as TOML gives it
    assert back == c and back.multiview.camera_offset_prior_px == (("a", 1.5), ("b", 1.5))
    with pytest.raises(InputError, match=r"camera_offset_prior_px"):
        config_from_dict(Stage1Config, {"multiview": {"camera_offset_prior_px": [["a", 1.0]], "nope": 1}})


@dataclass(frozen=True)
class _Optional:
    size: tuple[int, int] | None = None


def test_optional_tuple_fields_take_arrays_as_tuples():
    assert config_from_dict(_Optional, {"size": [640, 480]}).size == (640, 480)
    assert config_from_dict(_Optional, {}).size is None
