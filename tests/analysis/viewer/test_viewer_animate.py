"""Animation export: GIF and MP4 files have the expected number of frames and size; options are checked;
MP4 without imageio-ffmpeg says how to get it; the Jupyter display; the still used by the report."""
from __future__ import annotations

import builtins

import numpy as np
import pytest
from PIL import Image

from flocksweep.analysis.viewer import animate
from flocksweep.analysis.viewer.animation import (AnimationUnavailable, check_options, frame_count, poster, source_frames,
                                     write_animation)
from viewer_data import milling_track


@pytest.fixture(scope="module")
def track():
    return milling_track(with_scene=False, n=12, frames=31, dt=0.1)  # 3 s recorded at 10 Hz


def test_frame_times_follow_fps_and_speed(track):
    assert frame_count(track, 10, 1.0) == 31
    assert frame_count(track, 4, 2.0) == 7            # 3 s at 2x, 4 fps: 0, 0.5, ..., 3.0 s
    np.testing.assert_array_equal(source_frames(track, 4, 2.0), [0, 5, 10, 15, 20, 25, 30])
    assert list(source_frames(track, 25, 1.0)[:6]) == [0, 0, 1, 1, 2, 2]  # nearest recorded frame (0.04 s apart)


@pytest.mark.slow   # over half a second of CPU: out of the quick loop (CI runs it)
def test_gif_has_the_expected_frames_and_size(track, tmp_path):
    out = write_animation(track, tmp_path / "flock.gif", fps=5, speed=1.0, size=(320, 240), color_by="pattern")
    assert out.frames == 16 and (out.width, out.height) == (320, 240) and out.format == "gif"
    with Image.open(tmp_path / "flock.gif") as gif:
        assert gif.n_frames == 16
        assert gif.size == (320, 240)
        gif.seek(0)
        first = np.asarray(gif.convert("RGB"), dtype=int)
        gif.seek(15)
        last = np.asarray(gif.convert("RGB"), dtype=int)
    assert np.abs(first - last).max() > 50  # the flock moved (and the time stamp changed)
    # Holland's Table 1 colours of the two patterns (green 00111010, blue 11000101) are in the picture
    greenish = (last[..., 1] > 100) & (last[..., 0] < 80) & (last[..., 2] < 80)
    bluish = (last[..., 2] > 150) & (last[..., 0] < 80) & (last[..., 1] < 80)
    assert greenish.sum() > 20 and bluish.sum() > 20
    assert out._repr_html_().startswith("<img src='data:image/gif;base64,")


@pytest.mark.slow
def test_mp4_has_the_expected_frames_and_size(track, tmp_path):
    import imageio_ffmpeg

    out = animate(track, tmp_path / "flock.mp4", fps=8, speed=1.5, rotate=True, size=(320, 240), color_by="group")
    assert out.frames == frame_count(track, 8, 1.5) == 17
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(tmp_path / "flock.mp4"))
    assert frames == 17
    reader = imageio_ffmpeg.read_frames(str(tmp_path / "flock.mp4"))
    meta = next(reader)
    assert tuple(meta["size"]) == (320, 240)
    first = np.frombuffer(next(reader), np.uint8).reshape(240, 320, 3)
    assert first.std() > 5
    reader.close()
    assert "<video" in out._repr_html_()


def test_mp4_without_imageio_ffmpeg_says_what_to_install(track, tmp_path, monkeypatch):
    real_import = builtins.__import__

    def no_ffmpeg(name, *args, **kwargs):
        if name == "imageio_ffmpeg":
            raise ImportError("no imageio_ffmpeg here")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ffmpeg)
    with pytest.raises(AnimationUnavailable, match=r"pip install imageio-ffmpeg.*GIF export works without it"):
        write_animation(track, tmp_path / "x.mp4", size=(320, 240))
    assert not (tmp_path / "x.mp4").exists()


def test_options_are_checked(tmp_path):
    for path, kwargs, message in [
            (tmp_path / "a.webm", {}, ".gif or .mp4"),
            (tmp_path / "a.gif", {"fps": 0}, "fps"),
            (tmp_path / "a.gif", {"speed": -1}, "speed"),
            (tmp_path / "a.gif", {"size": (8, 8)}, "size"),
            (tmp_path / "a.gif", {"size": (100000, 100000)}, "from 16 to 3840"),
            (tmp_path / "a.gif", {"size": (640, 3841)}, "from 16 to 3840"),
            (tmp_path / "a.mp4", {"size": (321, 240)}, "even width"),
            (tmp_path / "a.gif", {"color_by": "mood"}, "color_by")]:
        options = {"fps": 20, "speed": 1, "size": (320, 240), "dpi": 100, "color_by": "auto", **kwargs}
        with pytest.raises(ValueError, match=message):
            check_options(path, **options)


def test_poster_is_a_png_of_the_requested_size(track, tmp_path):
    path = poster(track, tmp_path / "still.png", size=(300, 200))
    with Image.open(path) as image:
        assert image.format == "PNG" and image.size == (300, 200)
        assert np.asarray(image.convert("L")).std() > 5
