"""The walk before a trip, cached on disk: the same arrays as computing it, keyed by what
the kinematics depend on."""

import numpy as np
import pytest

from stumble.body import build
from stumble.gait import walk_cache
from stumble.gait.playback import walk


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv(walk_cache.CACHE_ENV, str(tmp_path))
    return tmp_path / "walks"


def _same(a, b) -> bool:
    return (all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("time_s", "qpos", "qvel"))
            and a.coordinates.keys() == b.coordinates.keys()
            and all(np.array_equal(a.coordinates[k], b.coordinates[k]) for k in a.coordinates)
            and a.events == b.events and (a.speed_m_per_s, a.stride_s, a.source, a.retarget,
                                          a.notes) == (b.speed_m_per_s, b.stride_s, b.source,
                                                       b.retarget, b.notes)
            and a.shown_qpos is not None and np.array_equal(a.shown_qpos, b.shown_qpos))


def test_a_cached_walk_is_the_computed_walk_bit_for_bit(cache, monkeypatch):
    body = build(planar=True)
    fresh = walk(body, 1.2, duration_s=1.5)  # the trips' start states
    first = walk_cache.walk_cached(body, 1.2, 1.5)
    assert len(list(cache.glob("*.npz"))) == 1
    assert _same(fresh, first)

    def no_compute(*a, **k):
        raise AssertionError("a cached walk was computed again")

    monkeypatch.setattr(walk_cache, "walk", no_compute)
    again = walk_cache.walk_cached(build(planar=True, contact="soft", timestep_s=0.002), 1.2, 1.5)
    assert _same(fresh, again)  # contact mode and time step do not enter the key


def test_the_key_follows_body_speed_and_duration(cache):
    a = build()
    key = walk_cache.walk_key(a, 1.2, 4.4)
    assert walk_cache.walk_key(build(contact="points"), 1.2, 4.4) == key
    assert len({key, walk_cache.walk_key(a, 1.3, 4.4), walk_cache.walk_key(a, 1.2, 4.0),
                walk_cache.walk_key(build(height_m=1.6), 1.2, 4.4),
                walk_cache.walk_key(build(sex="female"), 1.2, 4.4),
                walk_cache.walk_key(build(planar=True), 1.2, 4.4)}) == 6


def test_an_unreadable_file_is_computed_again(cache):
    body = build(planar=True)
    path = cache / f"{walk_cache.walk_key(body, 1.0, 1.5)}.npz"
    cache.mkdir(parents=True)
    path.write_bytes(b"not a walk")
    pb = walk_cache.walk_cached(body, 1.0, 1.5)
    assert pb.qpos.shape[1] == body.model.nq
    assert _same(pb, walk_cache.walk_cached(body, 1.0, 1.5))  # replaced by a good file


def test_off_turns_the_cache_off(tmp_path, monkeypatch):
    monkeypatch.setenv(walk_cache.CACHE_ENV, "off")
    assert walk_cache.cache_dir() is None
    monkeypatch.setenv(walk_cache.CACHE_ENV, str(tmp_path / "c"))
    assert walk_cache.cache_dir() == tmp_path / "c"
