"""The videos' overlay: every frame says the time, the place, the transition being executed, the push."""

from __future__ import annotations

import numpy as np
import pytest

from multiform.report.video import draw_lines, frame_labels, overlay_frames, write_mp4

from .test_plots import trace_with


def test_each_frame_is_labelled_with_time_place_transition_and_push():
    tr = trace_with([(0.0, "t0"), (1.0, "t2"), (2.5, "t1")], seconds=4.0)
    tr.marking[2500:, 1], tr.marking[2500:, 2] = 0, 1
    tr.qpos_every = 100
    labels = frame_labels(tr, 100, 40, push_time=3.0)
    assert labels[0] == ["t =   0.00 s", "place: P1", "transition: t0"]
    assert labels[12] == ["t =   1.20 s", "place: P1", "transition: t2"]
    assert labels[26] == ["t =   2.60 s", "place: P2", "transition: t1"]
    assert [i for i, lab in enumerate(labels) if "PUSH" in lab] == [30, 31, 32, 33, 34, 35]
    frames = [np.full((120, 160, 3), 90, np.uint8) for _ in range(40)]
    out = list(overlay_frames(frames, tr, push_time=3.0))
    assert len(out) == 40 and all(f.shape == (120, 160, 3) for f in out)
    assert not np.array_equal(out[0], frames[0]) and not np.array_equal(out[0], out[12])   # the text changes
    red = lambda f: ((f[:, :, 0] > 180) & (f[:, :, 1] < 120)).sum()  # noqa: E731
    assert red(out[30]) > 10 and red(out[29]) == 0


def test_drawing_leaves_the_rest_of_the_frame_alone():
    frame = np.full((100, 200, 3), 77, np.uint8)
    out = draw_lines(frame, ["t = 1.00 s"])
    assert np.array_equal(out[60:, :], frame[60:, :]) and np.array_equal(frame, np.full_like(frame, 77))


def test_videos_use_the_ffmpeg_program_and_say_so_when_it_is_missing(tmp_path, monkeypatch):
    from multiform.report.video import read_mp4
    frames = [np.full((48, 64, 3), 40 * k, dtype=np.uint8) for k in range(6)]
    path = write_mp4(frames, tmp_path / "a.mp4", fps=10)
    back = read_mp4(path)
    assert back.shape == (6, 48, 64, 3) and np.abs(back.astype(int) - np.stack(frames)).max() <= 8
    monkeypatch.setenv("MULTIFORM_FFMPEG", str(tmp_path / "no-ffmpeg"))
    with pytest.raises(RuntimeError, match="install the ffmpeg program"):
        write_mp4(frames, tmp_path / "b.mp4")
    assert not (tmp_path / "b.mp4").exists()
