"""The compiled kernels of the reflex controllers (``stumble.control.reflex.kernels``):
each the same numbers as the NumPy code it stands in for, alone and over whole walks and
trips of both controllers."""

from dataclasses import replace

import numpy as np
import pytest

from stumble.control.reflex import kernels as K
from stumble.control.reflex.receptors import GTOFilter, _linear_filter

pytest.importorskip("numba")


@pytest.fixture
def compiled():
    """The compiled kernels (Numba is in the dev extra), restored after the test."""
    K.use_numpy(False)
    k = K.kernels()
    if k is None:
        pytest.skip(f"{K.ENV}=numpy in the environment")
    yield k
    K.use_numpy(False)


def _arrays(rec) -> dict:
    return {k: v for k, v in vars(rec).items() if isinstance(v, np.ndarray)}


def _same_runs(run) -> None:
    """``run()`` gives every recorded array the same, bit for bit, with the compiled
    kernels and with the NumPy code."""
    K.use_numpy(False)
    if K.kernels() is None:
        pytest.skip(f"{K.ENV}=numpy in the environment")
    fast = _arrays(run())
    K.use_numpy(True)
    try:
        ref = _arrays(run())
    finally:
        K.use_numpy(False)
    assert fast.keys() == ref.keys()
    assert len(ref["time_s"]) > 100
    for name, a in ref.items():
        assert np.array_equal(fast[name], a, equal_nan=True), name


def test_second_order_filter_is_scipys_lfilter_bit_for_bit(compiled):
    """``iir2`` is SciPy's filter kernel, to the bit, on the tendon organ's filter."""
    g = GTOFilter(0.001, 16)
    rng = np.random.default_rng(3)
    for n in (1, 5, 8, 20):
        x = rng.uniform(0.0, 300.0, (n, 16))
        z = rng.uniform(-500.0, 500.0, (2, 16))
        y_ref, z_ref = (_linear_filter(g.b, g.a, x, 0, z) if _linear_filter is not None
                        else pytest.skip("SciPy without its filter kernel"))
        y, zz = np.empty_like(x), z.copy()
        compiled["iir2"](g.b, g.a, x, zz, y)
        assert np.array_equal(y, y_ref) and np.array_equal(zz, z_ref)


def test_trunk_balance_kernel_equals_numpy(compiled):
    """``TrunkBalance.drive_cols`` compiled and in NumPy, every option on, on loads that
    cross the stance threshold and feet that pass each other."""
    from stumble.control.reflex.controller import TrunkBalance

    rng = np.random.default_rng(4)
    sensed = np.column_stack([rng.uniform(-0.5, 0.5, 64), rng.uniform(-3, 3, 64),
                              rng.uniform(0, 900, (64, 2)), rng.uniform(-0.4, 0.4, (64, 2))])
    sensed[::7, 2:4] = 0.0  # no load at all: the half shares
    for rectified in (False, True):
        bal = TrunkBalance(kp_per_rad=1.6, kd_s_per_rad=0.5, lean_ref_rad=-0.1,
                           rectified=rectified, k_lean=0.23, stance_load=0.28, k_bw=0.9)
        fast = bal.drive_cols(sensed)
        K.use_numpy(True)
        ref = bal.drive_cols(sensed)
        K.use_numpy(False)
        assert np.array_equal(fast, ref)
        assert np.abs(ref).max() > 0.1  # it drives something


def test_network_walk_and_trips_compiled_equal_numpy():
    """The closed-loop network's walk and a trip, and the open-loop network's trip: the
    same recordings with and without the kernels."""
    from stumble.control.reflex.identify import default_network
    from stumble.pipeline import simulate_trip, simulate_walk
    from stumble.trip import Scenario

    _same_runs(lambda: simulate_walk("network", 2.0).recording)
    sc = Scenario(controller="reflex", start="playback", mechanism="obstacle", swing_fraction=0.13,
                  speed_m_per_s=1.2, duration_after_trip_s=0.6)
    _same_runs(lambda: simulate_trip(sc).recording)
    open_loop = default_network("open-loop")
    _same_runs(lambda: simulate_trip(sc.with_(swing_fraction=0.56),
                                     network=open_loop).recording)
    net = default_network("closed-loop")  # a copy whose balance carries a placement law
    placing = replace(net, info={**net.info, "balance": dict(
        net.info["balance"], k_place=0.5, place_a0=0.15, place_cd=0.1, place_cv=0.05)})
    _same_runs(lambda: simulate_walk("network", 1.0, network=placing).recording)


def test_numpys_own_loops_are_found_and_give_numpys_bits(compiled):
    """``numpy_loops``: NumPy's inner loops of tanh, exp, log, power, arctan2 and matmul
    are found on this NumPy and, called from the kernels, give NumPy's bits on arrays
    other than the load-time check's (contiguous, in place, strided, a scalar exponent,
    the networks' matrix products); a loop that is not float64's is refused."""
    loops = compiled["loops"]
    assert loops is not None, "NumPy's loops not found: the network's block is not fused"
    rng = np.random.default_rng(7)
    meta = np.zeros(16, dtype=np.int64)
    h = rng.normal(0.0, 2.0, (8, 2, 42))
    ref = np.tanh(h)
    compiled["loop1"](loops, K.TANH, meta, h, h)  # in place, as the network runs it
    assert np.array_equal(h, ref)
    t = rng.normal(0.0, 5.0, (8, 2, 8))
    out = np.empty_like(t)
    compiled["loop1"](loops, K.EXP, meta, t, out)
    assert np.array_equal(out, np.exp(t))
    fin = rng.uniform(1.0, 30.0, (8, 14))
    compiled["loop1"](loops, K.LOG, meta, fin, out := np.empty_like(fin))
    assert np.array_equal(out, np.log(fin))
    compiled["loop_pow"](loops, meta, fin, 0.6, out)
    assert np.array_equal(out, np.power(fin, 0.6))
    g = rng.normal(0.0, 1.0, (8, 7))
    lean = np.empty(8)
    compiled["loop_atan2_cols"](loops, meta, g, 0, 1, lean)
    assert np.array_equal(lean, np.arctan2(g[:, 0], g[:, 1]))
    x, w = rng.normal(0.0, 1.0, (8, 2, 70)), rng.normal(0.0, 0.3, (70, 42))
    got, want = np.empty((8, 2, 42)), np.empty((8, 2, 42))
    compiled["loop_matmul"](loops, meta, x, w, got)
    np.matmul(x, w, out=want)
    assert np.array_equal(got, want)
    assert K._loop_address(np.add, "OO->O") is None  # object loops: not float64's
    assert K._loop_address(np.tanh, "f->f") is None


def test_kernels_close_over_nothing_compiled_so_that_numbas_cache_holds(compiled):
    """Numba keys a cached function by the pickled values of its closure cells, and a
    compiled function (or intrinsic) pickles differently in every process: a kernel that
    closed over another would be compiled again in each (seconds a process). Each kernel
    reaches the others as module globals instead."""
    for name, fn in compiled.items():
        if name == "loops":
            continue
        cells = fn.py_func.__closure__ or ()
        held = [type(c.cell_contents).__name__ for c in cells
                if hasattr(c.cell_contents, "py_func") or "Intrinsic" in
                type(c.cell_contents).__name__]
        assert not held, (name, held)


def test_loops_that_do_not_give_numpys_bits_are_not_used(compiled, monkeypatch):
    """``numpy_loops`` checks each loop against NumPy before the kernels use it: with
    exp's address standing in for tanh's (a layout read wrongly), it refuses them all,
    and the blocks run as separate calls."""
    real = K._loop_address
    monkeypatch.setattr(K, "_loop_address", lambda uf, sig: real(
        np.exp if uf is np.tanh else uf, sig))
    assert K.numpy_loops(compiled) is None
    monkeypatch.setattr(K, "_loop_address", real)
    assert K.numpy_loops(compiled) is not None


@pytest.mark.parametrize("controller", ["reflex", "gh2010"])
def test_the_fused_block_equals_the_calls_it_fuses(controller):
    """A reflex controller's block as one compiled call (NumPy's loops in it) and as the
    separate compiled and NumPy calls: the same late-swing trip with the touch's
    reflexes, bit for bit."""
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    K.use_numpy(False)
    kern = K.kernels()
    if kern is None or kern["loops"] is None:
        pytest.skip("no compiled kernels or NumPy's loops not found")
    sc = Scenario(controller=controller, mechanism="obstacle", swing_fraction=0.6,
                  speed_m_per_s=1.2, start="own", duration_after_trip_s=1.0)
    fused = simulate_trip(sc).recording
    loops, kern["loops"] = kern["loops"], None
    try:
        apart = simulate_trip(sc).recording
    finally:
        kern["loops"] = loops
    assert len(fused.time_s) > 100
    for name, a in _arrays(apart).items():
        assert np.array_equal(_arrays(fused)[name], a, equal_nan=True), name


def test_the_touch_afferent_compiled_equals_numpy_and_is_silent_at_zero():
    """A network with the touch afferent: with its weights 0 the trip is the network's
    own, bit for bit; with weights, the same recordings with and without the kernels,
    and a different trip from the moment the touch arrives."""
    from stumble.control.reflex.fit_walk import network_space, network_with
    from stumble.control.reflex.identify import default_network
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    net = default_network("placement-es")
    sc = Scenario(controller="reflex", start="playback", mechanism="obstacle", swing_fraction=0.13,
                  speed_m_per_s=1.2, duration_after_trip_s=0.6)
    plain = simulate_trip(sc, network=net).recording
    silent = simulate_trip(sc, network=net.with_touch()).recording
    assert np.array_equal(plain.qpos, silent.qpos)
    space = network_space(net.with_touch(), False)
    theta = space.start.copy()
    theta[[n.startswith("touch_") for n in space.names]] = 3.0
    touched = network_with(net.with_touch(), theta)
    _same_runs(lambda: simulate_trip(sc, network=touched).recording)
    rec = simulate_trip(sc, network=touched).recording
    n = min(len(rec.qpos), len(plain.qpos))
    differs = np.flatnonzero(np.abs(rec.qpos[:n] - plain.qpos[:n]).max(axis=1) > 0)
    assert len(differs) and rec.time_s[differs[0]] > 0.02  # after the touch's path


@pytest.mark.parametrize("variant", [
    {},  # the `pushed` set: placement, touch reflexes, crossing step
    {"wiring": "seed003"},  # the network's expert wiring (double support via the lean)
    {"load_from": "any", "scr_phase": "foot", "g_scr_ext_glu": 0.5, "g_scr_ext_rf": 0.5,
     "place_cd": 0.2, "place_cv": 0.1, "delay_scale": 1.5},
])
def test_gh2010_trips_compiled_equal_numpy(variant):
    """Geyer & Herr's trips from their own gait, with the options that change the
    kernels' paths: the same recordings with and without the kernels."""
    from stumble.control.reflex.gh2010 import load_params, shipped_params
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    base = shipped_params("seed003") if variant.get("wiring") == "seed003" else \
        load_params("pushed")
    params = replace(base, **{k: v for k, v in variant.items() if k != "wiring"})
    sc = Scenario(controller="gh2010", mechanism="obstacle", swing_fraction=0.65,
                  speed_m_per_s=1.2, duration_after_trip_s=0.8,
                  start="playback" if variant.get("wiring") else "own")
    _same_runs(lambda: simulate_trip(sc, gh2010=params).recording)


def test_numpy_is_forced_by_the_environment(monkeypatch):
    """``STUMBLE_KERNELS=numpy`` runs the NumPy code even where Numba is installed."""
    monkeypatch.setenv(K.ENV, "numpy")
    K.use_numpy(False)
    try:
        assert K.kernels() is None
    finally:
        monkeypatch.delenv(K.ENV)
        K.use_numpy(False)
    assert K.kernels() is not None


def test_kernels_that_cannot_be_built_leave_the_numpy_code_with_a_warning(monkeypatch):
    """If Numba is there but the kernels cannot be built (say, no writable cache), the
    NumPy code runs, with one warning, rather than every reflex run failing."""
    def broken(numba):
        raise RuntimeError("cannot cache function: no locator available")

    monkeypatch.setattr(K, "_compiled", broken)
    K.use_numpy(False)
    try:
        with pytest.warns(RuntimeWarning, match="NumPy code runs"):
            assert K.kernels() is None
    finally:
        monkeypatch.undo()
        K.use_numpy(False)
    assert K.kernels() is not None


@pytest.mark.parametrize("timestep", [0.002, 0.001])
def test_the_touch_response_compiled_equals_numpy_and_starts_after_its_latency(timestep):
    """A network's touch response (``TouchResponse``): with its gains 0 the trip is the
    network's own, bit for bit; with gains, the same recordings with and without the
    kernels (at 2 ms and at 1 ms, where the kernel writes the plan), and a different
    trip from 65 ms after the touch, not before."""
    from stumble.control.reflex.fit_walk import network_space, network_with
    from stumble.control.reflex.identify import default_network
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    net = default_network("placement-es")
    sc = Scenario(controller="reflex", start="playback", mechanism="obstacle", swing_fraction=0.13,
                  speed_m_per_s=1.2, duration_after_trip_s=0.5, timestep_s=timestep)
    plain = simulate_trip(sc, network=net).recording
    silent = simulate_trip(sc, network=net.with_touch_response()).recording
    assert np.array_equal(plain.qpos, silent.qpos)
    with_resp = net.with_touch_response()
    space = network_space(with_resp, touch_only=True, touch_response=True)
    theta = np.where([n.startswith("resp_ipsi") for n in space.names], 0.4, space.start)
    touched = network_with(with_resp, theta, space.names)
    _same_runs(lambda: simulate_trip(sc, network=touched).recording)
    rec = simulate_trip(sc, network=touched).recording
    n = min(len(rec.qpos), len(plain.qpos))
    differs = np.flatnonzero(np.abs(rec.qpos[:n] - plain.qpos[:n]).max(axis=1) > 0)
    assert len(differs) and 0.065 < rec.time_s[differs[0]] < 0.15


def _native_runs(monkeypatch, run):
    """``run()`` with whole blocks in one compiled call, the physics included
    (``ReflexController.run_blocks``), and block by block (``sim.native_physics`` off):
    (the two results, the blocks the first ran natively)."""
    import stumble.sim as sim
    from stumble.control.reflex.controller import ReflexController
    from stumble.control.reflex.gh2010 import GH2010Controller

    K.use_numpy(False)
    kern = K.kernels()
    if kern is None or kern["loops"] is None:
        pytest.skip("no compiled kernels or NumPy's loops not found")
    native_blocks = []
    for cls in (ReflexController, GH2010Controller):
        def counted(self, *a, _real=cls.run_blocks):
            got = _real(self, *a)
            native_blocks.append(0 if got is None else got[3])
            return got

        monkeypatch.setattr(cls, "run_blocks", counted)
    fast = run()
    monkeypatch.setattr(sim, "native_physics", lambda m, d: None)
    return fast, run(), sum(native_blocks)


@pytest.mark.parametrize("controller", ["reflex", "gh2010"])
@pytest.mark.parametrize("case", ["walk", "pushed walk", "case1", "own-lowering",
                                  "own-elevating", "force"])
def test_blocks_run_natively_equal_block_by_block(monkeypatch, controller, case):
    """Each reflex controller's walk, with two pelvis pushes (blocks under a push stay
    Python), its CASE 1 trip from the recording (the network's touch response, Geyer &
    Herr's stumbling reflexes; a fall), own-gait trips (the walk to the trip stopped by
    ``TripTimer``) and a force trip: whole blocks in one compiled call, the physics
    included, give the recording and the summary of block-by-block stepping, bit for bit,
    and most blocks do run natively."""
    from stumble.pipeline import simulate_trip, simulate_walk
    from stumble.trip import Scenario

    if case in ("walk", "pushed walk"):
        pushes = ((1.0, 0.2, -150.0), (2.2, 0.2, 150.0)) if case == "pushed walk" else ()

        def run():
            return simulate_walk("network" if controller == "reflex" else "gh2010", 3.0,
                                 speed_m_per_s=1.0, pushes=pushes)
    else:
        sc = {"case1": Scenario(controller="reflex", start="playback", mechanism="obstacle",
                                swing_fraction=0.13, speed_m_per_s=1.2,
                                duration_after_trip_s=3.0),
              "own-lowering": Scenario(controller="reflex", mechanism="obstacle",
                                       swing_fraction=0.7, speed_m_per_s=1.2, start="own"),
              "own-elevating": Scenario(controller="reflex", mechanism="obstacle",
                                        swing_fraction=0.1, speed_m_per_s=1.4,
                                        start="own"),
              "force": Scenario(controller="reflex", mechanism="force", swing_fraction=0.3,
                                speed_m_per_s=1.0, start="own")}[case].with_(
            controller=controller)

        def run():
            return simulate_trip(sc)
    fast, ref, n_native = _native_runs(monkeypatch, run)
    a, b = _arrays(fast.recording), _arrays(ref.recording)
    assert a.keys() == b.keys() and len(b["time_s"]) > 100
    for name, x in b.items():
        assert np.array_equal(a[name], x, equal_nan=True), name
    assert fast.recording.stop_reason == ref.recording.stop_reason
    assert ({k: v for k, v in fast.summary.items() if k != "wall_time_s"}
            == {k: v for k, v in ref.summary.items() if k != "wall_time_s"})
    steps = ref.recording.steps if "walk" in case else len(b["time_s"]) * 2
    per_block = 4 if controller == "reflex" else 2  # steps a block at 2 ms
    assert n_native * per_block > 0.5 * steps


def test_the_walk_to_a_trip_stops_natively_where_block_by_block_does(monkeypatch):
    """An own-gait trip's walk, stopped at the trip instant by ``TripTimer`` (its quiet
    time, the foot it watches): natively the same instant, and the controller goes on
    from the same state (the same trip after it)."""
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    sc = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.45,
                  speed_m_per_s=1.0, start="own", duration_after_trip_s=1.0)
    fast, ref, n_native = _native_runs(monkeypatch, lambda: simulate_trip(sc))
    assert n_native > 500  # the walk to the trip, 4 s and more, mostly native
    assert fast.summary["walk_in"] == ref.summary["walk_in"]
    assert np.array_equal(fast.recording.qpos, ref.recording.qpos)


def test_native_physics_reads_mujocos_warnings_and_refuses_what_a_rollout_resets():
    """``sim.native_physics``: its view of the data's warning counters is MuJoCo's; a
    model with mocap bodies (which a rollout resets each block) is refused."""
    import mujoco

    import stumble.sim as sim

    m = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/></body></worldbody>"
        "</mujoco>")
    d = mujoco.MjData(m)
    phys = sim.native_physics(m, d)
    assert phys is not None and phys.warnings.shape == (len(d.warning), 2)
    bad = int(mujoco.mjtWarning.mjWARN_BADQACC)
    d.warning[bad].number = 3
    assert phys.warnings[bad, 1] == 3
    phys.warnings[bad, 1] = 0
    assert d.warning[bad].number == 0
    mocap = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body mocap='true'><geom size='.1'/></body></worldbody>"
        "</mujoco>")
    assert sim.native_physics(mocap, mujoco.MjData(mocap)) is None


def test_native_blocks_in_threads_give_each_runs_own_numbers():
    """Two walks and two trips at once in threads (a Dask worker may run trips so; the
    compiled loops release the GIL): each the numbers it has alone."""
    from concurrent.futures import ThreadPoolExecutor

    from stumble.pipeline import simulate_trip, simulate_walk
    from stumble.trip import Scenario

    K.use_numpy(False)
    if K.kernels() is None:
        pytest.skip(f"{K.ENV}=numpy in the environment")
    jobs = [lambda: simulate_walk("network", 2.0, speed_m_per_s=1.0).recording,
            lambda: simulate_walk("gh2010", 2.0, speed_m_per_s=1.2).recording,
            lambda: simulate_trip(Scenario(controller="reflex", start="playback",
                                           mechanism="obstacle",
                                           swing_fraction=0.13, speed_m_per_s=1.2,
                                           duration_after_trip_s=1.0)).recording,
            lambda: simulate_trip(Scenario(controller="gh2010", mechanism="obstacle",
                                           swing_fraction=0.3, speed_m_per_s=1.0,
                                           duration_after_trip_s=1.0)).recording]
    alone = [job() for job in jobs]
    with ThreadPoolExecutor(4) as ex:
        together = list(ex.map(lambda job: job(), jobs))
    for a, b in zip(alone, together, strict=True):
        assert len(a.time_s) > 100
        assert np.array_equal(a.qpos, b.qpos) and np.array_equal(a.sensordata, b.sensordata)
