"""Offscreen rendering of a motion (qpos trajectory) to an mp4 video or a PNG filmstrip.

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` once, when ``import mujoco`` runs
(MuJoCo 4.0 imports ``mujoco.rendering.classic.gl_context`` inside ``mujoco/__init__``), so
by the time a model exists it is too late to change the variable for this process. Here the
backends are probed once per process in a child Python (so a missing or broken GL library can
neither crash nor hang us): the user's ``MUJOCO_GL`` if set, else ``egl`` then ``osmesa``. The
working one is written to ``os.environ`` (for child processes) and, if this process's mujoco
was imported with another backend (e.g. the GLFW default, which needs a display), the
renderer's context class is swapped for that one while the :class:`mujoco.Renderer` is built.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import math
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from stumble.errors import InputError, StumbleError

__all__ = ["render_frames", "render_video", "save_filmstrip", "video_available"]

APT_HINT = "apt-get install libegl1 libgl1-mesa-dri libegl-mesa0"
MSG_NO_GL = f"video disabled: no OpenGL (install Mesa EGL: `{APT_HINT}`, then MUJOCO_GL=egl)"
MSG_NO_MP4 = "video disabled: install the extra `pip install 'stumble[video]'`"

_AUTO_BACKENDS = ("egl", "osmesa")
_OFF_VALUES = ("disable", "disabled", "off", "false", "0")
_PROBE_TIMEOUT_S = 45.0
_PROBE_OK = "STUMBLE_GL_PROBE_OK"
_PROBE_SCRIPT = f"""
import mujoco
m = mujoco.MjModel.from_xml_string(
    '<mujoco><worldbody><light pos="0 0 2"/><geom type="sphere" size="0.1"/></worldbody></mujoco>')
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
r = mujoco.Renderer(m, 32, 32)
r.update_scene(d)
img = r.render()
r.close()
assert img.shape == (32, 32, 3), img.shape
print("{_PROBE_OK}")
"""

_BACKEND_MODULES = {"egl": "mujoco.egl", "osmesa": "mujoco.osmesa", "glfw": "mujoco.glfw"}
_SWAP_LOCK = threading.Lock()

# Camera defaults: on the person's left (+y) looking toward −y, slightly from above.
DEFAULT_DISTANCE_M = 3.5
DEFAULT_AZIMUTH_DEG = -90.0
DEFAULT_ELEVATION_DEG = -12.0
DEFAULT_SMOOTH_S = 0.25

_TILE_M = 0.5  # checker tiles drawn on an untextured floor


# --------------------------------------------------------------------------- availability
def _one_line(text: str, limit: int = 140) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 1] + "…"


def _probe_backend(backend: str) -> tuple[bool, str]:
    """Try offscreen rendering with ``MUJOCO_GL=backend`` in a child Python."""
    env = dict(os.environ)
    env["MUJOCO_GL"] = backend
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE_SCRIPT],
            env=env,
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            timeout=_PROBE_TIMEOUT_S,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return False, f"timed out after {_PROBE_TIMEOUT_S:.0f} s"
    except OSError as exc:
        return False, _one_line(f"{type(exc).__name__}: {exc}")
    if proc.returncode == 0 and _PROBE_OK in proc.stdout:
        return True, ""
    tail = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
    reason = tail[-1] if tail else f"exit code {proc.returncode}"
    return False, _one_line(reason, 100)


@functools.cache
def _gl_status() -> tuple[str | None, str]:
    """(working backend or None, one-line message when None). Probed once per process."""
    requested = os.environ.get("MUJOCO_GL", "").strip().lower()
    if requested in _OFF_VALUES:
        return None, (f"video disabled: MUJOCO_GL={requested} turns rendering off "
                      "(unset it or set MUJOCO_GL=egl)")
    if requested:
        ok, reason = _probe_backend(requested)
        if ok:
            return requested, ""
        return None, (f"video disabled: MUJOCO_GL={requested} cannot render offscreen here "
                      f"({_one_line(reason, 60)}); use Mesa EGL: `{APT_HINT}`, "
                      "then MUJOCO_GL=egl")
    for backend in _AUTO_BACKENDS:
        ok, _reason = _probe_backend(backend)
        if ok:
            os.environ["MUJOCO_GL"] = backend
            return backend, ""
    return None, MSG_NO_GL


@functools.cache
def _mp4_status() -> tuple[bool, str]:
    """Whether imageio + imageio-ffmpeg can write an H.264 mp4 (a tiny real write)."""
    try:
        import imageio.v2 as iio
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except Exception:  # any import or exe failure means "not installed"
        return False, MSG_NO_MP4
    try:
        with tempfile.TemporaryDirectory(prefix="stumble-mp4-") as tmp:
            probe = Path(tmp) / "probe.mp4"
            writer = iio.get_writer(probe, format="FFMPEG", mode="I", fps=10, codec="libx264",
                                    pixelformat="yuv420p", macro_block_size=2,
                                    ffmpeg_log_level="error")
            frame = np.zeros((16, 16, 3), np.uint8)
            for _ in range(2):
                writer.append_data(frame)
            writer.close()
            if probe.stat().st_size <= 0:
                raise OSError("empty file")
    except Exception as exc:
        return False, _one_line(
            f"video disabled: ffmpeg cannot write H.264 mp4 ({type(exc).__name__}); "
            "reinstall the extra `pip install 'stumble[video]'`")
    return True, ""


def video_available() -> tuple[bool, str]:
    """Whether offscreen rendering and mp4 writing both work here.

    Returns ``(True, "")`` or ``(False, one-line message telling how to enable video)``.
    The probe runs once per process (GL in a child process, never crashing or hanging
    this one) and is cached.
    """
    ok, msg = _mp4_status()
    if not ok:
        return False, msg
    backend, msg = _gl_status()
    if backend is None:
        return False, msg
    return True, ""


def _require_gl() -> str:
    backend, msg = _gl_status()
    if backend is None:
        raise StumbleError(msg)
    return backend


# --------------------------------------------------------------------------- GL context
def _renderer_gl_module():
    """The module whose ``GLContext`` attribute mujoco.Renderer instantiates."""
    module = sys.modules.get(mujoco.Renderer.__module__)
    return getattr(module, "gl_context", None)


@contextlib.contextmanager
def _backend_for_renderer(backend: str) -> Iterator[None]:
    """Make a Renderer built inside this block use ``backend``'s GL context class."""
    gl_module = _renderer_gl_module()
    module_name = _BACKEND_MODULES.get(backend)
    if gl_module is None or module_name is None:
        yield
        return
    try:
        wanted = importlib.import_module(module_name).GLContext
    except Exception as exc:
        raise StumbleError(_one_line(
            f"video disabled: cannot load the {backend} OpenGL backend in this process "
            f"({type(exc).__name__}: {exc})")) from exc
    with _SWAP_LOCK:
        current = getattr(gl_module, "GLContext", None)
        if current is wanted:
            yield
            return
        gl_module.GLContext = wanted
        try:
            yield
        finally:
            gl_module.GLContext = current


@contextlib.contextmanager
def _offscreen_size(model: mujoco.MjModel, width: int, height: int) -> Iterator[None]:
    """Temporarily enlarge the model's offscreen buffer if the image is bigger than it."""
    glob = model.vis.global_
    old = (int(glob.offwidth), int(glob.offheight))
    glob.offwidth = max(old[0], width)
    glob.offheight = max(old[1], height)
    try:
        yield
    finally:
        glob.offwidth, glob.offheight = old


def _make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    backend = _require_gl()
    try:
        with _backend_for_renderer(backend), _offscreen_size(model, width, height):
            renderer = mujoco.Renderer(model, height=height, width=width)
    except StumbleError:
        raise
    except Exception as exc:
        raise StumbleError(_one_line(
            f"video disabled: cannot create an OpenGL context with MUJOCO_GL={backend} "
            f"({type(exc).__name__}: {exc})")) from exc
    flags = renderer.scene.flags
    flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
    flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
    return renderer


# --------------------------------------------------------------------------- camera/scene
@dataclass(frozen=True)
class _Camera:
    track_body: str = "pelvis"
    distance: float = DEFAULT_DISTANCE_M
    azimuth_deg: float = DEFAULT_AZIMUTH_DEG
    elevation_deg: float = DEFAULT_ELEVATION_DEG


def _even(n: int, name: str) -> int:
    n = int(n)
    if n < 2:
        raise InputError(f"{name} must be at least 2 pixels, got {n}")
    return n - (n % 2)


def _as_qpos(model: mujoco.MjModel, qpos) -> np.ndarray:
    arr = np.asarray(qpos, dtype=float)
    if arr.ndim == 1 and arr.shape[0] == model.nq:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != model.nq or arr.shape[0] < 1:
        raise InputError(
            f"qpos must have shape (T, {model.nq}) with T >= 1, got {tuple(arr.shape)}")
    if not np.all(np.isfinite(arr)):
        raise InputError("qpos contains NaN or Inf values; cannot render")
    return arr


def _body_id(model: mujoco.MjModel, name: str) -> int:
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid < 0:
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) or f"#{i}"
                 for i in range(1, min(model.nbody, 8))]
        more = ", ..." if model.nbody > 8 else ""
        raise InputError(f"no body named '{name}' to track (bodies: {', '.join(names)}{more})")
    return bid


def _smooth(x: np.ndarray, sigma_frames: float) -> np.ndarray:
    """Zero-lag Gaussian smoothing with odd-reflection padding (keeps linear motion exact)."""
    n = x.shape[0]
    if sigma_frames < 0.5 or n < 3:
        return x.copy()
    r = min(math.ceil(3.0 * sigma_frames), n - 1)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma_frames) ** 2)
    k /= k.sum()
    left = 2.0 * x[0] - x[r:0:-1]
    right = 2.0 * x[-1] - x[-2:-r - 2:-1]
    return np.convolve(np.concatenate([left, x, right]), k, mode="valid")


def _track_points(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray, body: int,
                  sigma_frames: float) -> np.ndarray:
    """Camera look-at points (T, 3): smoothed body x, the clip's median body y and z."""
    pos = np.empty((qpos.shape[0], 3))
    for i, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        pos[i] = data.xpos[body]
    look = np.empty_like(pos)
    look[:, 0] = _smooth(pos[:, 0], sigma_frames)
    look[:, 1] = np.median(pos[:, 1])
    look[:, 2] = np.median(pos[:, 2])
    return look


@dataclass
class _Floor:
    geom: int  # floor geom id, or -1
    material: int  # material id to show on it, or -1
    tiles: bool  # draw checker tiles as extra scene geoms
    z: float
    rgba: np.ndarray


def _floor_look(model: mujoco.MjModel) -> _Floor:
    """Decide how the floor gets a checker look without changing the model.

    A floor with its own material is left alone; a plain floor in a model that has a textured
    material shows that material (chosen by name: checker/grid/floor/ground first); a model
    without materials gets flat checker tiles added to the scene only (decor geoms).
    """
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    if gid < 0:
        return _Floor(-1, -1, False, 0.0, np.zeros(4))
    rgba = np.array(model.geom_rgba[gid], dtype=float)
    z = float(model.geom_pos[gid][2])
    if model.geom_matid[gid] >= 0:
        return _Floor(gid, -1, False, z, rgba)
    if model.nmat > 0:
        textured = [i for i in range(model.nmat) if np.any(model.mat_texid[i] >= 0)]
        if textured:
            def rank(i: int) -> int:
                name = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MATERIAL, i) or "").lower()
                return 0 if any(w in name for w in ("checker", "grid", "floor", "ground")) else 1
            return _Floor(gid, min(textured, key=rank), False, z, rgba)
    return _Floor(gid, -1, True, z, rgba)


def _visible_tiles(scene: mujoco.MjvScene, floor_z: float, aspect: float,
                   reach: float) -> np.ndarray:
    """World centres (n, 3) of the dark checker tiles inside the camera's view frustum."""
    cam = scene.camera[0]
    pos = np.asarray(cam.pos, dtype=float)
    fwd = np.asarray(cam.forward, dtype=float)
    up = np.asarray(cam.up, dtype=float)
    right = np.cross(fwd, up)
    # centre of the search square: where the view axis meets the floor (or `reach` ahead)
    t = (floor_z - pos[2]) / fwd[2] if fwd[2] < -1e-6 else reach
    centre = pos + fwd * min(max(t, 0.0), reach)
    lo, hi = (centre[:2] - reach) / _TILE_M, (centre[:2] + reach) / _TILE_M
    ix = np.arange(math.floor(lo[0]), math.ceil(hi[0]))
    iy = np.arange(math.floor(lo[1]), math.ceil(hi[1]))
    gx, gy = np.meshgrid(ix, iy, indexing="ij")
    keep = (gx + gy) % 2 == 0
    pts = np.stack([(gx[keep] + 0.5) * _TILE_M, (gy[keep] + 0.5) * _TILE_M,
                    np.full(int(keep.sum()), floor_z + 0.001)], axis=1)
    rel = pts - pos
    z = rel @ fwd
    near = float(cam.frustum_near)
    half_h = 0.5 * (float(cam.frustum_top) - float(cam.frustum_bottom)) / near
    mid_v = 0.5 * (float(cam.frustum_top) + float(cam.frustum_bottom)) / near
    half_w = half_h * aspect
    mid_h = float(cam.frustum_center) / near
    margin = 0.75 * _TILE_M
    x, y = rel @ right, rel @ up
    vis = ((z > 0.05) & (z < 2.0 * reach)
           & (np.abs(x - mid_h * z) <= half_w * z + margin)
           & (np.abs(y - mid_v * z) <= half_h * z + margin))
    return pts[vis]


def _decorate_floor(scene: mujoco.MjvScene, model: mujoco.MjModel, floor: _Floor,
                    aspect: float, reach: float) -> None:
    if floor.geom < 0:
        return
    if floor.material >= 0:
        for j in range(scene.ngeom):
            g = scene.geoms[j]
            if g.objtype == mujoco.mjtObj.mjOBJ_GEOM and g.objid == floor.geom:
                g.matid = floor.material
                g.rgba[:] = model.mat_rgba[floor.material]
        return
    if not floor.tiles:
        return
    dark = floor.rgba.astype(np.float32)
    dark[:3] = np.clip(dark[:3] * 0.72, 0.0, 1.0)
    dark[3] = 1.0
    size = np.array([_TILE_M / 2, _TILE_M / 2, 0.0008])
    mat = np.eye(3).reshape(-1)
    box = mujoco.mjtGeom.mjGEOM_BOX
    for pos in _visible_tiles(scene, floor.z, aspect, reach):
        if scene.ngeom >= scene.maxgeom:
            break
        g = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(g, box, size, pos, mat, dark)
        g.category = mujoco.mjtCatBit.mjCAT_DECOR
        scene.ngeom += 1


def _iter_frames(model: mujoco.MjModel, qpos: np.ndarray, width: int, height: int,
                 cam: _Camera, sigma_frames: float) -> Iterator[np.ndarray]:
    """Yield rendered RGB frames (height, width, 3) uint8, one per qpos row."""
    body = _body_id(model, cam.track_body)
    data = mujoco.MjData(model)
    look = _track_points(model, data, qpos, body, sigma_frames)
    floor = _floor_look(model)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.distance = float(cam.distance)
    camera.azimuth = float(cam.azimuth_deg)  # MjvCamera takes degrees
    camera.elevation = float(cam.elevation_deg)
    reach = 2.0 * float(cam.distance)  # checker tiles are drawn about this far around
    renderer = _make_renderer(model, width, height)
    try:
        for i, q in enumerate(qpos):
            data.qpos[:] = q
            mujoco.mj_fwdPosition(model, data)
            camera.lookat[:] = look[i]
            renderer.update_scene(data, camera)
            _decorate_floor(renderer.scene, model, floor, width / height, reach)
            yield renderer.render()
    finally:
        renderer.close()


# --------------------------------------------------------------------------- overlay text
@functools.lru_cache(maxsize=256)
def _text_strip(text: str, width: int, strip_h: int) -> tuple[np.ndarray, np.ndarray]:
    """RGB (strip_h, width, 3) and alpha (strip_h, width, 1) of a translucent caption bar."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dpi = 100.0
    fig = Figure(figsize=(width / dpi, strip_h / dpi), dpi=dpi)
    fig.patch.set_facecolor((0.0, 0.0, 0.0, 0.55))
    canvas = FigureCanvasAgg(fig)
    fig.text(6.0 / width, 0.5, text, color="white", ha="left", va="center",
             fontsize=0.6 * strip_h * 72.0 / dpi, family="monospace")
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba(), dtype=np.float32)[:strip_h, :width] / 255.0
    fig.clear()
    return rgba[..., :3] * 255.0, rgba[..., 3:4]


def _draw_text(frame: np.ndarray, text: str) -> np.ndarray:
    if not text:
        return frame
    h, w = frame.shape[:2]
    strip_h = max(14, min(h, round(0.06 * h)))
    rgb, alpha = _text_strip(text, w, strip_h)
    top = frame[:strip_h].astype(np.float32)
    frame[:strip_h] = np.clip(top * (1.0 - alpha) + rgb * alpha + 0.5, 0, 255).astype(np.uint8)
    return frame


# --------------------------------------------------------------------------- progress bar
class _Progress:
    """A one-line ``\\r`` progress bar with percent and ETA on stderr."""

    def __init__(self, total: int, enabled: bool, label: str = "rendering") -> None:
        self.total = max(int(total), 1)
        self.enabled = enabled
        self.label = label
        self.start = time.perf_counter()
        self._last = -1.0
        self._shown = -1

    def update(self, done: int) -> None:
        if not self.enabled or done == self._shown:
            return
        now = time.perf_counter()
        if done < self.total and now - self._last < 0.1:
            return
        self._last = now
        self._shown = done
        frac = min(max(done / self.total, 0.0), 1.0)
        elapsed = now - self.start
        if done >= self.total:
            tail = f"{elapsed:5.1f} s"
        elif done > 0:
            tail = f"ETA {elapsed * (self.total - done) / done:5.1f} s"
        else:
            tail = "ETA   ? s"
        bar = "#" * round(30 * frac)
        sys.stderr.write(f"\r{self.label} [{bar:<30}] {100 * frac:3.0f}% "
                         f"{done}/{self.total} {tail}")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            self.update(self.total)
            sys.stderr.write("\n")
            sys.stderr.flush()


# --------------------------------------------------------------------------- public API
def render_frames(
    model: mujoco.MjModel,
    qpos_list: Sequence[np.ndarray] | np.ndarray,
    *,
    width: int = 640,
    height: int = 480,
    track_body: str = "pelvis",
    distance: float = DEFAULT_DISTANCE_M,
    azimuth_deg: float = DEFAULT_AZIMUTH_DEG,
    elevation_deg: float = DEFAULT_ELEVATION_DEG,
    smooth_frames: float = 0.0,
) -> list[np.ndarray]:
    """Render one RGB uint8 image (height, width, 3) per pose in ``qpos_list``.

    The camera looks from the person's left (+y toward −y), ``distance`` metres from the
    tracked body, each frame centred on its x (``smooth_frames`` > 0: Gaussian sigma in
    frames for a smoothed follow). Raises StumbleError when offscreen GL is unavailable.
    """
    qpos = _as_qpos(model, np.asarray(qpos_list, dtype=float))
    cam = _Camera(track_body, distance, azimuth_deg, elevation_deg)
    w, h = _even(width, "width"), _even(height, "height")
    return [f.copy() for f in _iter_frames(model, qpos, w, h, cam, smooth_frames)]


def render_video(
    path,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    *,
    width: int = 640,
    height: int = 480,
    track_body: str = "pelvis",
    overlay: Sequence[str] | None = None,
    progress: bool = True,
    distance: float = DEFAULT_DISTANCE_M,
    azimuth_deg: float = DEFAULT_AZIMUTH_DEG,
    elevation_deg: float = DEFAULT_ELEVATION_DEG,
    smooth_s: float = DEFAULT_SMOOTH_S,
) -> Path:
    """Render ``qpos`` (T, nq) to an H.264 mp4 (yuv420p) at ``fps``; return the path.

    The camera follows the tracked body's x smoothly (Gaussian, ``smooth_s`` seconds) from the
    person's left side; shadows and reflections are off. ``overlay`` (T strings) is drawn as a
    caption on each frame. Odd sizes are rounded down to even. Raises StumbleError (one line)
    when video is not available here.
    """
    ok, msg = video_available()
    if not ok:
        raise StumbleError(msg)
    fps = float(fps)
    if not (math.isfinite(fps) and fps > 0):
        raise InputError(f"fps must be a positive number, got {fps}")
    q = _as_qpos(model, qpos)
    n = q.shape[0]
    if overlay is not None and len(overlay) != n:
        raise InputError(f"overlay has {len(overlay)} lines but qpos has {n} frames")
    w, h = _even(width, "width"), _even(height, "height")
    cam = _Camera(track_body, distance, azimuth_deg, elevation_deg)

    import imageio.v2 as iio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    frames = _iter_frames(model, q, w, h, cam, max(float(smooth_s), 0.0) * fps)
    bar = _Progress(n, progress, label=f"video {path.name}")
    writer = iio.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                            pixelformat="yuv420p", macro_block_size=2, quality=7,
                            ffmpeg_log_level="error")
    done = False
    try:
        bar.update(0)
        for i, frame in enumerate(frames):
            if overlay is not None:
                frame = _draw_text(frame, str(overlay[i]))
            writer.append_data(frame)
            bar.update(i + 1)
        done = True
    finally:
        frames.close()
        writer.close()
        if done:
            bar.close()
        else:
            if progress:
                sys.stderr.write("\n")
            path.unlink(missing_ok=True)
    return path


def save_filmstrip(path, frames: Sequence[np.ndarray], labels: Sequence[str] | None = None,
                   dpi: float = 100.0, columns: int | None = None) -> Path:
    """Tile frames left to right (``columns`` per row; default all in one row) into one
    PNG with a label above each; return the path.

    One row is ``columns * frame_width`` pixels wide and ``frame_height + 30`` tall.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    frames = [np.asarray(f) for f in frames]
    if not frames:
        raise InputError("save_filmstrip needs at least one frame")
    h, w = frames[0].shape[:2]
    if any(f.shape[:2] != (h, w) for f in frames):
        raise InputError("all filmstrip frames must have the same size")
    if labels is not None and len(labels) != len(frames):
        raise InputError(f"{len(labels)} labels for {len(frames)} filmstrip frames")
    n = columns or len(frames)
    rows = -(-len(frames) // n)
    label_h = 30
    row_h = h + label_h
    total_w, total_h = n * w, rows * row_h
    fig = Figure(figsize=(total_w / dpi, total_h / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    fig.patch.set_facecolor("white")
    try:
        for i, frame in enumerate(frames):
            r, c = divmod(i, n)
            bottom = (rows - 1 - r) * row_h / total_h
            ax = fig.add_axes((c / n, bottom, 1.0 / n, h / total_h))
            ax.imshow(frame, interpolation="nearest", aspect="auto")
            ax.set_axis_off()
            if labels is not None:
                fig.text((c + 0.5) / n, bottom + (h + 0.5 * label_h) / total_h,
                         str(labels[i]), ha="center", va="center",
                         fontsize=0.45 * label_h * 72.0 / dpi)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=dpi, format="png")
    finally:
        fig.clear()
    return path
