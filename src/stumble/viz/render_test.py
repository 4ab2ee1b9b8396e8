"""Offscreen rendering: availability probe, mp4 output, tracking camera, filmstrip."""

import os
import subprocess
import sys

import matplotlib.image as mpimg
import mujoco
import numpy as np
import pytest

from stumble.errors import InputError, StumbleError
from stumble.viz import render
from stumble.viz.render import render_frames, render_video, save_filmstrip, video_available

TEST_XML = """
<mujoco>
  <worldbody>
    <light pos="0 0 4" directional="true" dir="0 0 -1"/>
    <geom name="floor" type="plane" size="0 0 0.1"/>
    <geom name="post" type="box" size="0.06 0.06 0.3" pos="0.8 0 0.3" rgba="0 1 0 1"/>
    <body name="pelvis" pos="0 0 1">
      <freejoint/>
      <geom type="capsule" size="0.12 0.3" rgba="1 0 0 1"/>
    </body>
  </worldbody>
</mujoco>
"""


def _model():
    return mujoco.MjModel.from_xml_string(TEST_XML)


def _walk(model, n=10, dist=5.0):
    q = np.tile(model.qpos0, (n, 1))
    q[:, 0] = np.linspace(0.0, dist, n)
    return q


def _require_video():
    ok, msg = video_available()
    if not ok:
        pytest.skip(msg)


def _red_mask(frame):
    f = frame.astype(int)
    return (f[..., 0] > 110) & (f[..., 1] < 70) & (f[..., 2] < 70)


def _green_mask(frame):
    f = frame.astype(int)
    return (f[..., 1] > 110) & (f[..., 0] < 80) & (f[..., 2] < 80)


def test_video_available_returns_bool_and_one_line():
    ok, msg = video_available()
    assert isinstance(ok, bool)
    assert isinstance(msg, str)
    if ok:
        assert msg == ""
    else:
        assert msg and "\n" not in msg and msg.startswith("video disabled")
    assert video_available() == (ok, msg)  # cached


def test_disabled_gl_gives_one_line_message():
    code = ("from stumble.viz.render import video_available\n"
            "ok, msg = video_available()\nprint(ok)\nprint(msg)\n")
    env = dict(os.environ, MUJOCO_GL="disable")
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=120, check=True)
    lines = proc.stdout.strip().splitlines()
    assert lines[0] == "False"
    assert len(lines) == 2 and "MUJOCO_GL" in lines[1]


def test_missing_imageio_gives_install_hint(monkeypatch):
    render._mp4_status.cache_clear()
    try:
        monkeypatch.setitem(sys.modules, "imageio", None)
        monkeypatch.setitem(sys.modules, "imageio.v2", None)
        ok, msg = video_available()
        assert ok is False
        assert "pip install 'stumble[video]'" in msg and "\n" not in msg
    finally:
        monkeypatch.undo()
        render._mp4_status.cache_clear()


def test_render_video_raises_when_unavailable(monkeypatch, tmp_path):
    monkeypatch.setattr(render, "video_available", lambda: (False, "video disabled: test"))
    m = _model()
    with pytest.raises(StumbleError, match="video disabled: test"):
        render_video(tmp_path / "x.mp4", m, _walk(m), 10.0)
    assert not (tmp_path / "x.mp4").exists()


def test_smoothing_keeps_linear_motion_and_damps_jitter():
    ramp = np.linspace(0.0, 5.0, 40)
    assert np.allclose(render._smooth(ramp, 3.0), ramp)
    rng = np.random.default_rng(0)
    noisy = ramp + rng.normal(0.0, 0.05, ramp.shape)
    assert np.std(render._smooth(noisy, 3.0) - ramp) < 0.6 * np.std(noisy - ramp)


def test_filmstrip_tiles_frames_with_labels(tmp_path):
    frames = [np.full((60, 80, 3), c, np.uint8) for c in (0, 120, 250)]
    out = save_filmstrip(tmp_path / "strip.png", frames, ["a", "b", "c"])
    img = mpimg.imread(out)
    assert img.shape[:2] == (60 + 30, 3 * 80)
    assert img[-1, 10, 0] < 0.05 and img[-1, 2 * 80 + 10, 0] > 0.9
    with pytest.raises(InputError):
        save_filmstrip(tmp_path / "bad.png", frames, ["only one"])


def test_render_video_writes_tracked_mp4(tmp_path, capsys):
    _require_video()
    import imageio.v2 as iio

    m = _model()
    q = _walk(m, 10, 5.0)
    states = [f"state {i // 4}" for i in range(10)]
    out = render_video(tmp_path / "walk.mp4", m, q, 10.0, width=321, height=240,
                       overlay=states, progress=True)
    assert out.exists() and out.stat().st_size > 0
    assert "100%" in capsys.readouterr().err

    reader = iio.get_reader(out, format="FFMPEG")
    frames = [np.asarray(f) for f in reader]
    reader.close()
    assert len(frames) == q.shape[0]
    assert frames[0].shape == (240, 320, 3)  # odd width rounded down to even
    for f in frames:
        assert f.std() > 5.0  # not one colour
        red = _red_mask(f)
        assert red.sum() > 50
        cx = np.nonzero(red)[1].mean()
        assert abs(cx - 160) < 0.1 * 320  # the body stays near the image centre
    # the camera moved: the fixed post near x=0.8 m is seen at the start, not 5 m later
    assert _green_mask(frames[0]).sum() > 20
    assert _green_mask(frames[-1]).sum() == 0
    # the caption strip at the top differs from the plain sky of a caption-free frame
    plain = render_frames(m, q[:1], width=320, height=240, smooth_frames=0)[0]
    assert np.abs(frames[0][:12].astype(int) - plain[:12].astype(int)).max() > 60


def test_render_frames_centres_each_pose(tmp_path):
    _require_video()
    m = _model()
    q = _walk(m, 3, 4.0)
    frames = render_frames(m, q, width=160, height=120)
    assert len(frames) == 3
    for f in frames:
        assert f.shape == (120, 160, 3) and f.dtype == np.uint8
        cx = np.nonzero(_red_mask(f))[1].mean()
        assert abs(cx - 80) < 10
    out = save_filmstrip(tmp_path / "film.png", frames, ["0 s", "1 s", "2 s"])
    assert mpimg.imread(out).shape[:2] == (150, 480)


def test_bad_inputs_raise_one_line_errors(tmp_path):
    _require_video()
    m = _model()
    q = _walk(m, 4)
    cases = [
        dict(qpos=q[:, :3]),
        dict(qpos=q, overlay=["a"]),
        dict(qpos=q, track_body="nobody"),
        dict(qpos=q, fps=0.0),
    ]
    for kwargs in cases:
        kwargs = dict(kwargs)
        fps = kwargs.pop("fps", 10.0)
        with pytest.raises(InputError) as err:
            render_video(tmp_path / "bad.mp4", m, kwargs.pop("qpos"), fps, progress=False,
                         **kwargs)
        assert "\n" not in str(err.value)
        assert not (tmp_path / "bad.mp4").exists()
