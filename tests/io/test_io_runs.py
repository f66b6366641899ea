"""Run identities of resumable output folders (``toolkit.io.runs``)."""

from __future__ import annotations

import json

import pytest

from toolkit.errors import InputError
from toolkit.io.runs import (
    RECORDING_ID_KEY,
    RUN_FILE,
    dataset_fingerprint,
    file_fingerprint,
    run_recording,
    start_run,
)


def _dataset(root, video=b"frames"):
    (root / "videos").mkdir(parents=True)
    (root / "calibration.toml").write_text("[cam00]\n")
    (root / "videos" / "cam00.mp4").write_bytes(video)
    return root


def test_dataset_fingerprint_follows_the_content(tmp_path):
    a = dataset_fingerprint(_dataset(tmp_path / "a"))
    assert a == dataset_fingerprint(_dataset(tmp_path / "b"))  # same files elsewhere
    assert a != dataset_fingerprint(_dataset(tmp_path / "c", b"other frames"))
    big = tmp_path / "big.bin"
    big.write_bytes(bytes(9 << 20))
    f0 = file_fingerprint(big)
    with open(big, "r+b") as f:  # a change near the end of a large file is seen
        f.seek((9 << 20) - 10)
        f.write(b"x")
    assert file_fingerprint(big) != f0


def test_start_run_resumes_only_the_same_run(tmp_path):
    out = tmp_path / "out"
    ident = {"dataset": "abc", "optimize": True}
    assert start_run(out, ident, log=None) is False
    stored = json.loads((out / RUN_FILE).read_text())
    assert len(stored.pop(RECORDING_ID_KEY)) == 32 and stored == ident  # the identity, and a recording id
    (out / "frames").mkdir()
    (out / "frames" / "000000.json").write_text("{}")
    assert start_run(out, dict(ident), log=None) is True
    with pytest.raises(InputError, match="optimize") as e:
        start_run(out, {"dataset": "abc", "optimize": False}, log=None)
    assert "--replace-stale" in str(e.value)
    lines = []
    assert start_run(out, {"dataset": "abc", "optimize": False}, replace_stale=True, log=lines.append) is False
    assert (tmp_path / "out.stale-1" / "frames" / "000000.json").exists()  # moved aside, not lost
    assert not (out / "frames").exists() and "out.stale-1" in lines[0]


def test_start_run_refuses_a_foreign_folder(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="without a run.json"):
        start_run(out, {"dataset": "abc"}, log=None)
    (out / RUN_FILE).write_text("{not json")
    with pytest.raises(InputError, match="run.json"):
        start_run(out, {"dataset": "abc"}, log=None)


def test_run_recording_never_overwrites_an_earlier_part(tmp_path):
    out = tmp_path / "out"
    assert start_run(out, {"recipe": "r", "x": 1}, log=None) is False
    first, rid = run_recording(out, resumed=False)
    assert first == out / "recording.rrd"
    first.write_bytes(b"rrd")
    assert start_run(out, {"recipe": "r", "x": 1}, log=None) is True
    second, rid2 = run_recording(out, resumed=True)
    assert second == out / "recording.resume-1.rrd" and rid2 == rid  # one recording for the viewer
    second.write_bytes(b"rrd")
    third, rid3 = run_recording(out, resumed=True)
    assert third == out / "recording.resume-2.rrd" and rid3 == rid
    # a resumed run whose first part was never written starts at recording.rrd
    other = tmp_path / "other"
    start_run(other, {"recipe": "r", "x": 1}, log=None)
    path, rid_other = run_recording(other, resumed=True)
    assert path == other / "recording.rrd" and rid_other != rid  # another run: another recording
    # the id stays with the run when its folder moves; a run started afresh gets a new one
    moved = tmp_path / "moved"
    out.rename(moved)
    assert start_run(moved, {"recipe": "r", "x": 1}, log=None) is True
    assert run_recording(moved, resumed=True)[1] == rid
    assert start_run(moved, {"recipe": "r", "x": 2}, replace_stale=True, log=None) is False
    assert run_recording(moved, resumed=False)[1] not in (rid, rid_other)
    with pytest.raises(InputError, match="run.json"):
        run_recording(tmp_path / "never-started", resumed=False)
    with pytest.raises(InputError, match=RECORDING_ID_KEY):
        start_run(tmp_path / "x", {RECORDING_ID_KEY: "mine"}, log=None)

