"""The walk before a trip, cached on disk (it costs about a second per body and speed).

``walk_cached(body, speed, duration)`` returns exactly what ``playback.walk`` returns
(the same arrays, bit for bit, ``shown_qpos`` among them), from
``<cache dir>/walks/<key>.npz`` when a run has computed it before, in any process. The
key is a SHA-256 of everything the kinematics depend on: the body's model family,
height, mass and sex, the speed and duration, and the code and data that compute it (the
source of ``stumble.gait`` and ``stumble.body``, the reference gait, the versions of
stumble, MuJoCo and NumPy). The foot-contact mode, time step and muscles do not enter:
the sole points and segment lengths are the same in every mode. Files are written
atomically (a temporary file, then a rename), so parallel workers never read half a
file; an unreadable file is recomputed and replaced.

The cache directory is ``$STUMBLE_CACHE_DIR`` (``off`` turns the cache off), else
``$XDG_CACHE_HOME/stumble``, else ``~/.cache/stumble``. A directory that cannot be
written leaves the walk uncached (computed every time), never an error.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np

from stumble.body import Body
from stumble.gait import events as gait_events
from stumble.gait.playback import Playback, walk

CACHE_ENV = "STUMBLE_CACHE_DIR"
WALK_BEFORE_TRIP_S = 0.4  # the trip comes in the first swing of that leg after this time
WALK_S = WALK_BEFORE_TRIP_S + 2.5 * 1.6  # the walk played: room for a trip in any swing
FORMAT = 2  # bump when the file layout changes (2: with shown_qpos)


def cache_dir() -> Path | None:
    """Where walks are cached, or None when ``$STUMBLE_CACHE_DIR`` is ``off``."""
    env = os.environ.get(CACHE_ENV)
    if env is not None:
        return None if env.strip().lower() in ("off", "0", "") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "stumble"


@lru_cache(maxsize=1)
def code_hash() -> str:
    """SHA-256 of the source and data the walk is computed from, and the versions."""
    import mujoco

    import stumble
    from stumble import body as body_pkg
    from stumble import gait as gait_pkg

    h = hashlib.sha256()
    for pkg in (gait_pkg, body_pkg):
        root = Path(pkg.__file__).parent
        for path in sorted(root.rglob("*")):
            if (path.suffix in (".py", ".json") and path.is_file()
                    and not path.name.endswith("_test.py")):  # tests compute nothing
                h.update(str(path.relative_to(root)).encode())
                h.update(path.read_bytes())
    h.update(f"{stumble.__version__} {mujoco.__version__} {np.__version__} {FORMAT}".encode())
    return h.hexdigest()


def walk_key(body: Body, speed_m_per_s: float, duration_s: float) -> str:
    """The cache key (hex) of a body's walk at a speed for a duration."""
    fields = {"planar": bool(body.planar), "height_m": round(float(body.height_m), 10),
              "mass_kg": round(float(body.mass_kg), 10), "sex": body.sex,
              "speed_m_per_s": round(float(speed_m_per_s), 10),
              "duration_s": round(float(duration_s), 10), "code": code_hash()}
    text = json.dumps(fields, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def _save(path: Path, pb: Playback) -> None:
    meta = {"events": {"heel_strike_s": pb.events.heel_strike_s,
                       "toe_off_s": pb.events.toe_off_s},
            "speed_m_per_s": pb.speed_m_per_s, "stride_s": pb.stride_s, "source": pb.source,
            "retarget": pb.retarget, "notes": pb.notes, "names": list(pb.coordinates)}
    arrays = {"time_s": pb.time_s, "qpos": pb.qpos, "qvel": pb.qvel,
              "coordinates": np.array([pb.coordinates[n] for n in meta["names"]]),
              "meta": np.array(json.dumps(meta))}
    if pb.shown_qpos is not None:
        arrays["shown_qpos"] = pb.shown_qpos
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".walk-", suffix=".npz")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _load(path: Path, body: Body) -> Playback:
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        coords = dict(zip(meta["names"], z["coordinates"], strict=True))
        ev = gait_events.GaitEvents(meta["events"]["heel_strike_s"],
                                    meta["events"]["toe_off_s"])
        return Playback(body, z["time_s"], z["qpos"], z["qvel"], coords, ev,
                        meta["speed_m_per_s"], meta["stride_s"], meta["source"],
                        meta["retarget"], meta["notes"],
                        shown_qpos=z["shown_qpos"] if "shown_qpos" in z.files else None)


def walk_cached(body: Body, speed_m_per_s: float, duration_s: float) -> Playback:
    """``playback.walk(body, speed, duration)``, from the disk cache when it is there."""
    root = cache_dir()
    if root is None:
        return walk(body, speed_m_per_s, duration_s=duration_s)
    path = root / "walks" / f"{walk_key(body, speed_m_per_s, duration_s)}.npz"
    if path.is_file():
        try:
            return _load(path, body)
        except (OSError, ValueError, KeyError, TypeError):
            pass  # unreadable: computed again and replaced below
    pb = walk(body, speed_m_per_s, duration_s=duration_s)
    try:
        _save(path, pb)
    except OSError:
        pass  # a read-only or full disk: the walk stays uncached
    return pb


@lru_cache(maxsize=16)
def body_and_walk(height_m: float, mass_kg: float, sex: str, contact: str,
                  speed_m_per_s: float, timestep_s: float, planar: bool = False,
                  muscle_set: str | None = None) -> tuple[Body, Playback]:
    """The body and its walk before the trip; deterministic, so cached per process (and
    on disk across processes, ``walk_cached``). ``muscle_set``: the planar body's (None:
    ``stumble.body.muscles.DEFAULT_MUSCLE_SET``)."""
    from stumble.body import build
    from stumble.body.muscles import DEFAULT_MUSCLE_SET

    base = build(planar=planar, height_m=height_m, mass_kg=mass_kg, sex=sex, contact=contact,
                 timestep_s=timestep_s, actuation="muscles" if planar else "servos",
                 muscle_set=muscle_set or DEFAULT_MUSCLE_SET)
    return base, walk_cached(base, speed_m_per_s, WALK_S)
