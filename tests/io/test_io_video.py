"""Video writing and reading: round trip, random access, atomicity, bad input, real footage."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from toolkit.errors import InputError
from toolkit.io.video import VideoReader, VideoWriter, count_frames, probe_video, write_video

#: Mean absolute error (grey levels, per frame) of an mp4v round trip: measured
#: 3.3-4.1 on the small 96x64 frames below (seeds 0-3) and 2.4-2.8 re-encoding
#: the 1080x1920 Pose2Sim demo footage (the codec is lossy and stores colour at
#: half resolution).
VIDEO_MAE_TOL = 5.0
#: The same error on pure pixel noise is about 23: the bound above is not loose.
NOISE_MAE_MIN = 10.0


def smooth_frames(rng: np.random.Generator, n: int, size=(96, 64)) -> list[np.ndarray]:
    """A low-frequency random colour field drifting slowly, with a moving disc; RGB uint8."""
    w, h = size
    coarse = rng.uniform(30, 225, (3, 4, 3)).astype(np.float32)
    drift = rng.normal(0, 2.0, (3, 4, 3)).astype(np.float32)
    frames = []
    for i in range(n):
        img = cv2.resize(coarse + i * drift, (w, h), interpolation=cv2.INTER_CUBIC)
        img = np.clip(img, 0, 255).astype(np.uint8)
        cv2.circle(img, (10 + 6 * i, h // 2), h // 5, (240, 40, 40), -1)
        frames.append(img)
    return frames


def mae(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(np.int16) - b.astype(np.int16)).mean())


def test_round_trip(tmp_path):
    frames = smooth_frames(np.random.default_rng(0), 12)
    path = tmp_path / "sub" / "clip.mp4"
    assert write_video(path, iter(frames), fps=25) == 12
    assert sorted(p.name for p in path.parent.iterdir()) == ["clip.mp4"]
    info = probe_video(path)
    assert (info.n_frames, info.fps, info.size) == (12, 25.0, (96, 64))
    assert count_frames(path, exact=True) == 12
    with VideoReader(path) as video:
        assert len(video) == 12 and video.size == (96, 64) and video.fps == 25.0
        decoded = list(video)
        assert len(decoded) == 12
        for src, got in zip(frames, decoded):
            assert got.shape == (64, 96, 3) and got.dtype == np.uint8
            assert mae(src, got) < VIDEO_MAE_TOL
        # RGB order kept: the red disc is red
        assert decoded[0][32, 10, 0] > 200 and decoded[0][32, 10, 2] < 80
        # random access, backwards and forwards, gives the same pixels as sequential decoding
        for i in (7, 2, 2, 11, 0, -1):
            np.testing.assert_array_equal(video.read(i), decoded[i])
        with pytest.raises(IndexError):
            video.read(12)


def test_noise_is_lossy(tmp_path):
    """Guard for the tolerance above: the codec does lose detail on noise."""
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 256, (48, 64, 3), dtype=np.uint8) for _ in range(3)]
    write_video(tmp_path / "n.mp4", frames, fps=10)
    with VideoReader(tmp_path / "n.mp4") as video:
        assert mae(frames[1], video.read(1)) > NOISE_MAE_MIN


def test_streaming_writer_is_atomic(tmp_path):
    path = tmp_path / "v.mp4"
    frames = smooth_frames(np.random.default_rng(2), 3, size=(32, 32))
    w = VideoWriter(path, fps=30)
    w.write(frames[0])
    assert not path.exists()  # nothing at the destination until close
    w.write(frames[1])
    w.close()
    assert count_frames(path) == 2
    # a failing rewrite leaves the old file and no temporary behind
    with pytest.raises(InputError, match="frame 1"):
        write_video(path, [frames[0], frames[1][:16]], fps=30)
    assert count_frames(path) == 2
    assert [p.name for p in tmp_path.iterdir()] == ["v.mp4"]


@pytest.mark.parametrize(
    "frames,match",
    [
        ([], "at least one frame"),
        ([np.zeros((32, 32, 3), np.float32)], "uint8"),
        ([np.zeros((32, 32), np.uint8)], r"\(H, W, 3\)"),
        ([np.zeros((31, 32, 3), np.uint8)], "even width and height"),
        ([np.zeros((32, 32, 3), np.uint8), np.zeros((32, 34, 3), np.uint8)], "size 32x32"),
    ],
)
def test_bad_frames(tmp_path, frames, match):
    path = tmp_path / "bad.mp4"
    with pytest.raises(InputError, match=match) as err:
        write_video(path, frames, fps=25)
    assert str(path) in str(err.value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("fps", [0, -5, float("nan"), "25"])
def test_bad_fps(tmp_path, fps):
    with pytest.raises(InputError, match="fps"):
        VideoWriter(tmp_path / "v.mp4", fps)


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(InputError, match="no such file") as err:
        VideoReader(tmp_path / "none.mp4")
    assert str(tmp_path / "none.mp4") in str(err.value)
    fake = tmp_path / "fake.mp4"
    fake.write_text("this is not a video")
    for call in (VideoReader, count_frames, probe_video):
        with pytest.raises(InputError) as err:
            call(fake)
        assert str(fake) in str(err.value)
    with pytest.raises(InputError, match="folder"):
        count_frames(tmp_path)


def test_closed_reader_refuses(tmp_path):
    write_video(tmp_path / "v.mp4", smooth_frames(np.random.default_rng(3), 2, (32, 32)), 10)
    video = VideoReader(tmp_path / "v.mp4")
    video.close()
    with pytest.raises(InputError, match="closed"):
        video.read(0)


def test_pose2sim_video(pose2sim_demo):
    path = pose2sim_demo / "S00_P00_SingleParticipant/S00_P00_T01_BalancingTrial/videos/cam01.mp4"
    info = probe_video(path)
    assert (info.n_frames, info.fps, info.size) == (100, 60.0, (1080, 1920))
    assert count_frames(path, exact=True) == 100
    with VideoReader(path) as video:
        last = video.read(99)
        first = video.read(0)
        assert first.shape == (1920, 1080, 3) and last.shape == (1920, 1080, 3)
        assert np.abs(first.astype(int) - last).mean() > 0.5  # the person moves
        np.testing.assert_array_equal(video.read(99), last)
