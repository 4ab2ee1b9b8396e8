"""The reflex controller of seed 003: receptors, delays (Table I), identification,
the runtime network, and the emergence of both strategies from one network."""

from pathlib import Path

import numpy as np
import pytest

from stumble.body.muscles import MUSCLE_NAMES
from stumble.control.reflex import receptors as R
from stumble.control.reflex.controller import ReflexController
from stumble.control.reflex.identify import (
    default_network,
    fit,
    identify,
    static_optimisation,
)
from stumble.control.reflex.network import NERVE_LENGTH_M, Network, Topology
from stumble.errors import InputError
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario

J = {name: j for j, name in enumerate(MUSCLE_NAMES)}


# ---- receptors ---------------------------------------------------------------------
def test_spindle_rates():
    assert R.spindle_ia(0.0, 0.0) == pytest.approx(80.0)
    assert R.spindle_ii(0.001) == pytest.approx(80.0 + 13.5)
    assert R.spindle_ia(0.002, 0.0) == pytest.approx(84.0)
    # power law of stretch velocity, exponent 0.6 (Prochazka & Gorassini 1998)
    a = R.spindle_ia(0.0, 0.010) - 80.0
    b = R.spindle_ia(0.0, 0.020) - 80.0
    assert b / a == pytest.approx(2 ** 0.6)
    assert R.spindle_ia(-0.1, -1.0) == 0.0  # rates never go negative


def test_tendon_organ_law_and_filter():
    assert R.gto_static(4.0) == pytest.approx(60.0 * np.log(2.0))
    assert R.gto_static(0.0) == 0.0
    f = R.GTOFilter(0.001, 2)
    f.reset(np.array([100.0, 50.0]))
    for _ in range(100):
        y = f.step(np.array([100.0, 50.0]))
    assert y == pytest.approx([100.0, 50.0])  # unit DC gain, starts at steady state
    g = R.GTOFilter(0.001, 1)
    first = g.step(np.array([1.0]))
    assert first[0] == pytest.approx(1.7, abs=0.01)  # high-frequency gain 1.7/1


def test_tendon_organ_block_filter_is_lfilter_and_each_step():
    """``GTOFilter.block`` (SciPy's filter kernel, called directly) gives lfilter's numbers
    bit for bit, and those of filtering the samples one by one."""
    from scipy import signal

    x = 60.0 * np.abs(np.sin(np.arange(24.0)[:, None] * [0.3, 0.7, 1.1]))  # (24, 3) imp/s
    f = R.GTOFilter(0.001, 3)
    f.reset(x[0])
    z0 = f.z.copy()
    y, z = f.block(x)
    y_ref, z_ref = signal.lfilter(f.b, f.a, x, axis=0, zi=z0)
    assert np.array_equal(y, y_ref) and np.array_equal(z, z_ref)
    one = R.GTOFilter(0.001, 3)
    one.z[:] = z0
    stepped = np.array([one.step(row) for row in x])
    assert np.allclose(stepped, y, rtol=1e-12) and np.allclose(one.z, z, rtol=1e-12)
    assert not np.allclose(y, x)  # the filter does something: its high-frequency gain 1.7


# ---- delays of Table I ----------------------------------------------------------------
def test_nerve_delays_follow_table_one():
    t = Topology()
    d = t.path_delays_s()
    # SOL -> S1 -> SOL: 1.28 m afferent at 57.6 m/s plus 1.28 m efferent at 52.4 m/s
    assert d[("SOL", "S1", "SOL")] == pytest.approx(1.28 / 57.6 + 1.28 / 52.4)
    assert d[("RF", "L2", "VAS")] == pytest.approx(0.57 / 57.6 + 0.68 / 52.4)
    assert ("HAMS", "L2", "RF") not in d  # no HAMS fibre in L2 (Table I: —)
    seven = [v for k, v in NERVE_LENGTH_M.items() if k != "HFL"]
    assert len(t.connections()) == sum(len(v) for v in seven) == 19
    assert len(t.inputs()) == 3 * 19
    assert t.segments == ("L2", "L3", "L4", "L5", "S1", "S2")


def test_the_iliopsoas_enters_the_network_through_l1_to_l3():
    """HFL (optional) is bound to L1-L3 by its documented nerve lengths; L1 joins the
    segments only with it."""
    from stumble.body.muscles import MUSCLE_SETS

    t = Topology(muscles=MUSCLE_SETS["hfl"])
    assert t.segments == ("L1", "L2", "L3", "L4", "L5", "S1", "S2")
    assert len(t.connections()) == 19 + 3 and len(t.inputs()) == 3 * 22
    d = t.path_delays_s()
    assert d[("HFL", "L2", "HFL")] == pytest.approx(0.24 / 57.6 + 0.24 / 52.4)
    assert d[("RF", "L3", "HFL")] == pytest.approx(0.55 / 57.6 + 0.22 / 52.4)
    assert ("HAMS", "L5", "HFL") not in d


def test_contact_afferent_nerves_follow_the_plantar_nerves_roots():
    """The foot-contact afferents reach L4-L5 (TA's nerve + 0.35 m) and S1-S2 (SOL's +
    7 cm); at 1 kHz S1 and S2 both give a 23-sample delay."""
    from stumble.control.reflex.network import CONTACT_NERVE_M

    for seg in ("S1", "S2"):
        assert CONTACT_NERVE_M[seg] == pytest.approx(NERVE_LENGTH_M["SOL"][seg] + 0.07)
    for seg in ("L4", "L5"):
        assert CONTACT_NERVE_M[seg] == pytest.approx(NERVE_LENGTH_M["TA"][seg] + 0.35)
    t = Topology(contact=True)
    lags = {t.segments[s]: lag for s, sig, lag in t.inputs() if sig == 21}
    assert lags == {"L4": 25, "L5": 24, "S1": 23, "S2": 23}


def test_touch_afferent_enters_l4_to_s1_after_the_contact_signal(tmp_path):
    """The touch afferent (``Topology.touch``): one more signal per leg after the foot
    contact, into L4, L5 and S1 (the superficial peroneal nerve's roots) 25, 24 and 24
    ticks late at 1 kHz; ``with_touch`` keeps every other weight where it was, its own at
    0, and a file keeps it (a file without it loads without it)."""
    from stumble.control.reflex.identify import default_network
    from stumble.control.reflex.network import TOUCH_NERVE_M

    t = Topology(contact=True, touch=True)
    assert t.n_signals == 23 and t.touch_signal == 22
    lags = {t.segments[s]: lag for s, sig, lag in t.inputs() if sig == 22}
    assert lags == {"L4": 25, "L5": 24, "S1": 24}
    for seg in TOUCH_NERVE_M:
        assert TOUCH_NERVE_M[seg] == pytest.approx(NERVE_LENGTH_M["TA"][seg] + 0.35)
    net = default_network("placement-es")
    touch = net.with_touch()
    assert touch.topology.touch and not net.topology.touch
    old = {(s, sig): row for (s, sig, _l), row in zip(net.topology.inputs(), net.w,
                                                        strict=True)}
    for (s, sig, _l), row in zip(touch.topology.inputs(), touch.w, strict=True):
        want = np.zeros_like(row) if sig == touch.topology.touch_signal else old[(s, sig)]
        assert np.array_equal(row, want)
    assert touch.mean[-1] == 0.0 and touch.std[-1] == 1.0
    assert touch.walk_rates.shape[2] == net.walk_rates.shape[2] + 1
    assert not touch.walk_rates[:, :, -1].any()
    touch.save(tmp_path / "t.npz")
    back = Network.load(tmp_path / "t.npz")
    assert back.topology == touch.topology and np.array_equal(back.w, touch.w)
    net.save(tmp_path / "n.npz")
    assert not Network.load(tmp_path / "n.npz").topology.touch


def test_a_signal_reaches_a_muscle_exactly_after_its_path_delay():
    """A spike in SOL's tendon organ reaches SOL through S2 after 22 + 24 ms, TA through
    S1 after 22 + 20 ms, GLU through S2 after 22 + 9 ms, never earlier; RF and VAS
    (bound to L2-L4 only) never."""
    t = Topology()
    rng = np.random.default_rng(0)
    net = Network.initial(t, np.zeros(21), np.ones(21), seed=1)
    base = rng.normal(size=(400, 21))
    spiked = base.copy()
    spiked[100, 3 * J["SOL"] + 2] += 5.0
    du = np.abs(net.excitation(spiked) - net.excitation(base))
    first = {m: int(np.flatnonzero(du[:, J[m]] > 1e-12)[0]) if du[:, J[m]].max() > 1e-12
             else None for m in MUSCLE_NAMES}
    assert first["SOL"] == 100 + round(1.25 / 57.6 * 1000) + round(1.25 / 52.4 * 1000)
    assert first["TA"] == 100 + round(1.28 / 57.6 * 1000) + round(1.05 / 52.4 * 1000)
    assert first["GLU"] == 100 + round(1.25 / 57.6 * 1000) + round(0.47 / 52.4 * 1000)
    assert first["RF"] is None and first["VAS"] is None


def test_slower_nerves_lengthen_every_delay():
    t = Topology()
    slow = Network.initial(t, np.zeros(21), np.ones(21)).with_delay_scale(2.0).topology
    assert slow.max_lag == pytest.approx(2 * t.max_lag, abs=2)


# ---- network maths ---------------------------------------------------------------------
def test_gradient_matches_finite_differences():
    t = Topology(rate_hz=200.0, hidden=3)
    rng = np.random.default_rng(1)
    net = Network.initial(t, np.zeros(21), np.ones(21), seed=2)
    net.c = rng.normal(size=7)
    xd = net.delayed_inputs(rng.normal(size=(40, 21)))
    tgt = rng.uniform(size=(40, 7))

    def loss(th):
        net.unpack(th)
        return 0.5 * float(((net.forward(xd)[0] - tgt) ** 2).sum())

    th = net.pack()
    u, cache = net.forward(xd)
    g = net.gradient(xd, u - tgt, cache)
    for i in range(0, th.size, 11):
        e = np.zeros_like(th)
        e[i] = 1e-6
        assert (loss(th + e) - loss(th - e)) / 2e-6 == pytest.approx(g[i], abs=1e-6)


def test_controller_ticks_equal_the_batch_network():
    """The runtime ring buffers compute what the identification's shifted arrays do."""
    net = default_network()
    ctrl = ReflexController(net)
    ctrl._bind_network()
    t = net.topology
    rng = np.random.default_rng(4)
    sig = net.mean + net.std * rng.normal(size=(2, 150, t.n_signals))
    ticks = np.array([ctrl._tick(sig[:, k % 150]) for k in range(300)])[150:]
    batch = np.stack([net.excitation(sig[s]) for s in range(2)], axis=1)
    assert np.abs(ticks - batch).max() < 1e-12


def test_network_file_round_trip_and_errors(tmp_path):
    net = default_network()
    net.save(tmp_path / "n.npz")
    back = Network.load(tmp_path / "n.npz")
    assert np.array_equal(back.w, net.w) and back.info == net.info
    assert back.walk_rates.shape == net.walk_rates.shape
    with pytest.raises(InputError, match="does not exist"):
        Network.load(tmp_path / "missing.npz")
    (tmp_path / "bad.npz").write_bytes(b"not a numpy file")
    with pytest.raises(InputError, match=r"bad\.npz is not a network \.npz"):
        Network.load(tmp_path / "bad.npz")


# ---- bad network files: each refused in one line before it is loaded in full --------
def shipped_arrays() -> dict:
    from stumble.control.reflex.identify import SHIPPED

    path = Path(__file__).resolve().parent / "data" / SHIPPED
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def write_network(path, drop=(), **changes) -> Path:
    arrays = {**shipped_arrays(), **changes}
    np.savez_compressed(path, **{k: v for k, v in arrays.items() if k not in drop})
    return path


def _bad(tmp_path, name, make) -> Path:
    path = tmp_path / name
    make(path)
    return path


def test_the_shipped_layout_is_accepted_and_checked_against_its_own_muscles(tmp_path):
    from stumble.body.muscles import MUSCLE_SETS

    net = Network.load(write_network(tmp_path / "same.npz"))
    assert net.w.shape == (57, 36) and net.walk_rates.shape[0] == 2
    # eight muscles (with HFL, bound to L1-L3): checked as the layout its file says
    t = Topology(muscles=MUSCLE_SETS["hfl"])
    eight = Network.initial(t, np.zeros(t.n_signals), np.ones(t.n_signals), seed=0)
    eight.save(tmp_path / "eight.npz")
    back = Network.load(tmp_path / "eight.npz")
    assert back.muscle_set == "hfl" and back.w.shape == eight.w.shape != net.w.shape
    with pytest.raises(InputError, match=r"eight\.npz: a network of the muscles HAMS, GLU, TA, "
                       "GAS, RF, VAS, SOL, HFL; this model has HAMS, GLU, TA, GAS, RF, VAS, "
                       "SOL$"):
        Network.load(tmp_path / "eight.npz", muscles=MUSCLE_SETS["seed"])
    # six muscles (no SOL): a consistent file, but no muscle set of the body
    six = tuple(m for m in MUSCLE_NAMES if m != "SOL")
    t = Topology(muscles=six)
    other = Network.initial(t, np.zeros(t.n_signals), np.ones(t.n_signals), seed=0)
    other.save(tmp_path / "six.npz")
    with pytest.raises(InputError, match="a network of the muscles HAMS, GLU, TA, GAS, RF, "
                       "VAS, not a muscle set of the body"):
        Network.load(tmp_path / "six.npz")


BAD_NETWORKS = {
    "b of the wrong shape": (lambda p: write_network(p, b=np.zeros(35)),
                             r"b has shape \(35,\), expected \(36,\)"),
    "v of the wrong shape": (lambda p: write_network(p, v=np.zeros((19, 5))),
                             r"v has shape \(19, 5\), expected \(19, 6\)"),
    "walk_rates of the wrong shape": (lambda p: write_network(p, walk_rates=np.zeros((2, 9, 5))),
                                      r"walk_rates has shape \(2, 9, 5\)"),
    "rate_hz 0": (lambda p: write_network(p, rate_hz=np.array(0.0)), "rate_hz = 0 is outside"),
    "rate_hz NaN": (lambda p: write_network(p, rate_hz=np.array(np.nan)),
                    "rate_hz = nan is outside"),
    "afferent speed 0": (lambda p: write_network(p, afferent_m_per_s=np.array(0.0)),
                         "afferent_m_per_s = 0 is outside 1-200"),
    "NaN weights": (lambda p: write_network(p, w=np.where(shipped_arrays()["w"] != 0, np.nan, 0.0)),
                    "w holds 342 non-finite values"),
    "zero std": (lambda p: write_network(p, std=np.zeros(21)), "std has 21 values <= 0"),
    "wrong mean length": (lambda p: write_network(p, mean=np.zeros(20)),
                          r"mean has shape \(20,\), expected \(21,\)"),
    "weights outside their blocks": (lambda p: write_network(p, w=np.ones((57, 36))),
                                     "w has 1710 weights outside their segment blocks"),
    "a missing array": (lambda p: write_network(p, drop=("std",)),
                        "not a stumble reflex network \\(no std\\)"),
    "an unknown entry": (lambda p: write_network(p, extra=np.zeros(3)),
                         "unexpected entry 'extra.npy'"),
    "text where numbers belong": (lambda p: write_network(p, c=np.array(["a"] * 7)),
                                  "c has type <U1, not a number"),
    "an unknown muscle": (lambda p: write_network(p, muscles=np.array([*MUSCLE_NAMES[:6], "XYZ"])),
                          "each must be one of"),
    "eight muscles over a seven-muscle layout": (
        lambda p: write_network(p, muscles=np.array([*MUSCLE_NAMES, "HFL"])),
        "segments are not L1, L2, L3, L4, L5, S1, S2"),
    "info not JSON": (lambda p: write_network(p, info=np.array("{oops")), "info is not a JSON"),
    "a truncated zip": (lambda p: p.write_bytes(write_network(p).read_bytes()[:60_000]),
                        "is not a readable network .npz \\(BadZipFile"),
    "a .npy": (lambda p: np.save(p.with_suffix(".npy"), np.zeros(3))
               or p.with_suffix(".npy").rename(p), "is a single .npy array, not a network"),
    "a text file": (lambda p: p.write_text("rate_hz = 1000\n"), "not a zip archive"),
    "a directory": (lambda p: p.mkdir(), "is a directory, not a network file"),
    "an empty file": (lambda p: p.write_bytes(b""), "not a zip archive"),
}


@pytest.mark.parametrize("case", BAD_NETWORKS)
def test_bad_network_files_are_one_line_errors(tmp_path, case):
    make, words = BAD_NETWORKS[case]
    path = _bad(tmp_path, "net.npz", make)
    with pytest.raises(InputError, match=words) as e:
        Network.load(path)
    assert "\n" not in str(e.value) and str(path) in str(e.value)


def test_python_objects_in_a_network_are_refused_unread(tmp_path):
    arrays = shipped_arrays()
    arrays["info"] = np.array([{"a": 1}], dtype=object)
    np.savez(tmp_path / "obj.npz", **arrays)
    with pytest.raises(InputError, match=r"entry info\.npy holds Python objects"):
        Network.load(tmp_path / "obj.npz")


def test_a_network_that_inflates_past_the_limit_is_refused_from_its_directory(tmp_path):
    """64 MB of zeros in 64 KB: refused from the zip directory's sizes, before inflating."""
    import zipfile

    path = tmp_path / "bomb.npz"
    write_network(path, drop=("w",))
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as zf, zf.open("w.npy", "w") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False,
                                                 "shape": (8 * 2**20,)})
        zeros = bytes(2**20)
        for _ in range(64):
            f.write(zeros)
    assert path.stat().st_size < 2**20
    with pytest.raises(InputError, match=r"entry w inflates to 67108\d+ bytes, more than the "
                       r"33554432 bytes"):
        Network.load(path)


def test_a_header_that_does_not_match_its_data_is_refused(tmp_path):
    import zipfile

    path = tmp_path / "liar.npz"
    write_network(path, drop=("b",))
    with zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED) as zf, zf.open("b.npy", "w") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False,
                                                 "shape": (10**9,)})
        f.write(bytes(36 * 8))
    with pytest.raises(InputError, match=r"its header \(\(1000000000,\), float64\) does not "
                       "match"):
        Network.load(path)


# ---- identification ------------------------------------------------------------------
def test_static_optimisation_reproduces_reachable_moments():
    rng = np.random.default_rng(5)
    coef = np.array([[0.08, 0.05, 0], [0.1, 0, 0], [0, 0, -0.04], [0, 0.05, 0.05],
                     [-0.08, -0.06, 0], [0, -0.06, 0], [0, 0, 0.05]])
    gain = rng.uniform(500.0, 3000.0, (20, 7))
    passive = np.zeros((20, 7))
    a_true = rng.uniform(0.05, 0.5, (20, 7))
    moments = -(a_true * gain) @ coef
    a = static_optimisation(gain, passive, coef, moments, weight=1000.0)
    assert np.abs(-(a * gain) @ coef - moments).max() < 0.05  # N·m
    assert np.all(a >= 0.01 - 1e-12) and np.all(a <= 1.0 + 1e-12)
    # least squared activity: never more than the activity that made the moments
    assert np.all((a ** 2).sum(axis=1) <= (a_true ** 2).sum(axis=1) + 1e-6)


@pytest.fixture(scope="module")
def ident():
    return identify()


def test_walking_moments_are_reproduced_by_the_muscles(ident):
    err = ident.moments_nm - ident.moments_fit_nm
    rms = np.sqrt((err ** 2).mean(axis=(0, 1)))
    assert rms[2] < 0.5  # ankle: N·m, reproduced (SOL, GAS, TA suffice)
    assert np.all(rms < 5.0)  # hip and knee: within a few N·m of moments up to 65 N·m
    # ankle plantarflexion in late stance from SOL and GAS, swing from TA
    assert ident.activity[0, :, J["SOL"]].max() > 0.3
    assert 0.0 <= ident.activity.min() and ident.activity.max() <= 1.0


def test_fit_reaches_the_seeds_average_error_quickly(ident):
    r = fit(iterations=20, refine_iterations=150)
    assert r.report["avg_error"] < 0.03  # seed 003: 2.0 % after 1000 iterations
    assert r.report["paper_schedule"]["iterations"] == 20
    assert r.network.walk_rates.shape == (2, len(ident.time_s), 21)


def test_shipped_network_fits_walking_like_the_seed():
    info = default_network("open-loop").info
    assert info["avg_error"] < 0.02  # seed 003 §V.A: 2.0 %
    assert info["iterations"] >= 1000


# ---- emergence ---------------------------------------------------------------------------
@pytest.mark.parametrize("swing, expected", [(0.13, "elevating"), (0.56, "lowering")])
def test_both_strategies_emerge_from_one_network(swing, expected):
    """Seed 003 CASE 1 and CASE 2: same network, never switched, strategy from motion;
    the open-loop network, seed 003's identification alone (the default closed-loop one:
    controller_walk_test.py)."""
    r = simulate_trip(Scenario(controller="reflex", start="playback", swing_fraction=swing,
                               mechanism="obstacle", duration_after_trip_s=1.0),
                      network=default_network("open-loop"))
    s = r.summary
    assert s["strategy"] == expected
    assert not s["diverged"]
    assert s["states"] == [{"name": "reflex", "start_s": 0.0}]  # no switching
    if expected == "elevating":  # the foot came down beyond the obstacle's far face
        assert s["tripped_foot_down_x_m"] > s["obstacle_far_x_m"]
    else:
        assert s["tripped_foot_down_x_m"] < s["obstacle_far_x_m"] - 0.1


def test_reflex_is_not_told_a_strategy():
    with pytest.raises(InputError, match="emerges"):
        Scenario(controller="reflex", start="playback", strategy="elevating").validated()


def test_block_evaluation_equals_tick_by_tick(monkeypatch):
    """Evaluating the network once per block of ticks changes nothing but the speed."""
    from stumble.control.reflex import controller as C

    orig = C.ReflexController.__init__
    runs = {}
    for block in (1, None):
        def init(self, *args, _block=block, **kwargs):
            orig(self, *args, **{**kwargs, "block": _block})
        monkeypatch.setattr(C.ReflexController, "__init__", init)
        r = simulate_trip(Scenario(controller="reflex", start="playback", swing_fraction=0.3,
                                   mechanism="obstacle", duration_after_trip_s=0.5))
        runs[block] = r.recording
    assert len(runs[1].time_s) == len(runs[None].time_s) > 50
    assert np.abs(runs[1].qpos - runs[None].qpos).max() < 1e-9
    assert np.abs(runs[1].actuator_force - runs[None].actuator_force).max() < 1e-6


def test_tendon_organ_steady_state_is_exact():
    """The slow Ib filter (5 s) starts the walk at its periodic steady state: one more
    period from that state returns to it."""
    from scipy import signal

    rng = np.random.default_rng(7)
    x = np.abs(np.sin(np.linspace(0, 2 * np.pi, 1235, endpoint=False))[:, None]
               * rng.uniform(50, 200, 4))
    g = R.GTOFilter(0.001, 4)
    z0 = g.steady_state(x)
    _y, z1 = signal.lfilter(g.b, g.a, x, axis=0, zi=z0)
    assert np.abs(z1 - z0).max() < 1e-9 * max(1.0, np.abs(z0).max())
    y = g.periodic(x)
    z = g.state_at(x, 600)
    assert np.abs(signal.lfilter(g.b, g.a, x[600:], axis=0, zi=z)[0] - y[600:]).max() < 1e-9


def test_block_evaluation_at_2ms_equals_two_ticks_at_a_time(monkeypatch):
    """At a 2 ms step the network still ticks every 1 ms, each tick sensing its step's
    one row and each step holding its first tick's excitations: evaluated two ticks (one
    step) at a time or a block at a time, the same run."""
    from stumble.control.reflex import controller as C

    orig = C.ReflexController.__init__
    runs = {}
    for b in (None, 2):
        def init(self, *args, _block=b, **kwargs):
            orig(self, *args, **{**kwargs, "block": _block})
        monkeypatch.setattr(C.ReflexController, "__init__", init)
        r = simulate_trip(Scenario(controller="reflex", start="playback", swing_fraction=0.3,
                                   mechanism="obstacle", duration_after_trip_s=0.5,
                                   timestep_s=0.002))
        runs[b] = r
    assert runs[2].recording.steps == 250  # 0.5 s of 2 ms steps
    assert np.abs(runs[2].recording.qpos - runs[None].recording.qpos).max() < 1e-9


def test_network_tick_ratio():
    from stumble.control.reflex.network import tick_ratio

    assert tick_ratio(0.001) == (1, 1)
    assert tick_ratio(0.0005) == (2, 1)  # two steps a tick
    assert tick_ratio(0.002) == (1, 2)  # two ticks a step
    assert tick_ratio(0.003) == (1, 3)
    with pytest.raises(InputError, match=r"\(1\.5 ms\)"):
        tick_ratio(0.0015)


def test_reflex_time_step_must_divide_a_network_tick():
    with pytest.raises(InputError, match="must divide"):
        simulate_trip(Scenario(controller="reflex", start="playback", mechanism="obstacle",
                               swing_fraction=0.56, timestep_s=0.0015,
                               duration_after_trip_s=0.5))


def test_a_touch_response_is_checked_and_kept_in_the_networks_file(tmp_path):
    """``TouchResponse``: 65 ms late by default (Eng et al. 1994), its sets per muscle in
    ``info['touch_response']``, which a file keeps; a bad latency or an unknown muscle is
    one clear error; ``with_touch_response`` adds one with every gain 0."""
    from stumble.control.reflex.controller import TouchResponse
    from stumble.control.reflex.identify import default_network

    net = default_network("placement-es")
    resp_net = net.with_touch_response()
    r = TouchResponse.from_info(resp_net.info, net.topology.muscles)
    assert r.lag == 65 and not r.on and TouchResponse.from_info(net.info, ()) is None
    info = {**resp_net.info, "touch_response": {**resp_net.info["touch_response"],
                                                "contra": {"SOL": 0.4}, "hold_s": 0.12}}
    resp_net = Network(net.topology, net.w, net.b, net.v, net.c, net.mean, net.std, info,
                       net.walk_rates)
    resp_net.save(tmp_path / "r.npz")
    back = TouchResponse.from_info(Network.load(tmp_path / "r.npz").info,
                                   net.topology.muscles)
    assert back.on and back.hold == 120 and back.gains["contra"]["SOL"] == 0.4
    assert back.gains["contra"]["GAS"] == 0.0
    drive = back.drive(0, 400, np.array([10.0, -np.inf]))  # the right foot touched at 10
    sol = net.topology.muscles.index("SOL")
    on = np.flatnonzero(drive[:, 1, sol])  # the other (left) leg's SOL
    assert on[0] == 10 + 65 and on[-1] == 10 + 65 + 120 + 100 - 1
    assert not drive[:, 0].any()  # no ipsilateral gain
    slow = TouchResponse.from_info(resp_net.with_delay_scale(2.0).info, net.topology.muscles)
    assert (slow.lag, slow.hold, slow.after) == (130, 240, 200)  # delays x 2, as GH2010's
    with pytest.raises(InputError, match=r"latency_s = 0\.005"):
        TouchResponse(net.topology.muscles, latency_s=0.005)
    with pytest.raises(InputError, match="muscles the network does not drive"):
        TouchResponse(net.topology.muscles, {"ipsi": {"PSOAS": 1.0}})
    with pytest.raises(InputError, match="ipsi gain of TA is nan, not a finite number"):
        TouchResponse(net.topology.muscles, {"ipsi": {"TA": float("nan")}})
    with pytest.raises(InputError, match=r"unknown field\(s\) \['hold'\]"):
        TouchResponse.from_info({"touch_response": {"hold": 0.1}}, net.topology.muscles)


def test_a_response_by_the_foot_has_its_own_durations_for_the_foot_ahead():
    """``TouchResponse.by_foot`` with ``hold_ahead_s``/``after_ahead_s``: a touch of the
    foot ahead runs the ahead sets for their own durations, the foot behind's its own;
    both or neither, and only by the foot; a response asked by the foot of a network
    whose response is not is copied to both feet (the same drive); ``with_ahead_response``
    takes another network's ahead sets and durations, and refuses one that walks
    differently."""
    from stumble.control.reflex.controller import TouchResponse
    from stumble.control.reflex.identify import default_network

    muscles = default_network("placement-touch").topology.muscles
    sol = muscles.index("SOL")
    r = TouchResponse(muscles, {"contra": {"SOL": 0.5}, "contra_ahead": {"SOL": -0.3}},
                      hold_s=0.2, after_s=0.1, by_foot=True, hold_ahead_s=0.03,
                      after_ahead_s=0.15)
    behind = r.drive(0, 600, np.array([0.0, -np.inf]), np.array([False, False]))
    ahead = r.drive(0, 600, np.array([0.0, -np.inf]), np.array([True, False]))
    assert np.flatnonzero(behind[:, 1, sol]).tolist() == list(range(65, 65 + 300))
    assert np.flatnonzero(ahead[:, 1, sol]).tolist() == list(range(65, 65 + 180))
    assert set(ahead[:, 1, sol]) == {0.0, -0.3}
    assert r.running(65 + 299, 0.0) and not r.running(65 + 300, 0.0)  # the longer one
    back = TouchResponse.from_info({"touch_response": r.to_info()}, muscles)
    assert (back.hold_ahead, back.after_ahead) == (30, 150)
    with pytest.raises(InputError, match="hold_ahead_s and after_ahead_s both"):
        TouchResponse(muscles, by_foot=True, hold_ahead_s=0.1)
    with pytest.raises(InputError, match="by the foot's place"):
        TouchResponse(muscles, hold_ahead_s=0.1, after_ahead_s=0.1)

    touch, foot = default_network("placement-touch"), default_network("placement-foot")
    both = touch.with_touch_response(by_foot=True)
    r1 = TouchResponse.from_info(touch.info, muscles)
    r2 = TouchResponse.from_info(both.info, muscles)
    assert r2.by_foot and not r1.by_foot
    for side_ahead in (False, True):
        assert np.array_equal(r1.drive(0, 500, np.array([3.0, -np.inf])),
                              r2.drive(0, 500, np.array([3.0, -np.inf]),
                                       np.array([side_ahead, False])))
    mixed = touch.with_ahead_response(foot)
    rm = TouchResponse.from_info(mixed.info, muscles)
    rf = TouchResponse.from_info(foot.info, muscles)
    assert rm.gains["ipsi"] == r1.gains["ipsi"] and rm.hold == r1.hold
    assert rm.gains["ipsi_ahead"] == rf.gains["ipsi_ahead"]
    assert (rm.hold_ahead, rm.after_ahead) == (rf.hold, rf.after)
    with pytest.raises(InputError, match="walks differently"):
        default_network("closed-loop").with_touch_response().with_ahead_response(foot)
    with pytest.raises(InputError, match="no touch response by the foot"):
        touch.with_ahead_response(touch)


def test_the_recovery_step_drives_the_other_leg_from_the_touched_foots_landing():
    """``TouchResponse`` with ``cross_hold_s`` (``Network.with_cross_step``): from the
    touched foot's landing, the other leg's ``cross`` set for ``cross_hold_s``; kept in
    the file, scaled with the delays, fitted alone with ``cross_only``; with its gains 0
    a trip is the network's, bit for bit; a network without a response cannot have one."""
    from stumble.control.reflex.controller import TouchResponse
    from stumble.control.reflex.fit_walk import network_space
    from stumble.control.reflex.identify import default_network

    net = default_network("placement-both")
    muscles = net.topology.muscles
    hfl = muscles.index("HFL")
    r = TouchResponse(muscles, {"cross": {"HFL": 0.7}}, cross_hold_s=0.15)
    out = r.drive(0, 600, np.array([10.0, -np.inf]), landings=np.array([200.0, -np.inf]))
    assert np.flatnonzero(out[:, 1, hfl]).tolist() == list(range(200, 350))  # other leg
    assert not out[:, 0].any()
    assert not r.drive(0, 600, np.array([10.0, -np.inf])).any()  # no landing, no step
    back = TouchResponse.from_info({"touch_response": r.to_info()}, muscles)
    assert back.cross and back.cross_hold == 150 and back.gains["cross"]["HFL"] == 0.7
    crossed = net.with_cross_step()
    assert crossed.info["touch_response"]["cross_hold_s"] == 0.2
    # the landing is sensed through the sole's afferent (1.32 m of nerve), slower nerves later
    assert net.topology.load_lag() == 23
    assert net.with_delay_scale(2.0).topology.load_lag() == 46
    slow = TouchResponse.from_info(crossed.with_delay_scale(2.0).info, muscles)
    assert slow.cross_hold == 400
    space = network_space(crossed, touch_only=True, touch_response=True, cross_only=True)
    assert space.names == (*(f"resp_cross_{m}" for m in muscles), "resp_cross_hold_s")
    with pytest.raises(InputError, match="no touch response"):
        default_network("placement-walk").with_cross_step()
    sc = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.6,
                  speed_m_per_s=1.2, start="own", duration_after_trip_s=1.0)
    assert np.array_equal(simulate_trip(sc, network=net).recording.qpos,
                          simulate_trip(sc, network=crossed).recording.qpos)


def test_trips_of_networks_differing_only_in_their_touch_share_the_walk_to_the_trip():
    """Two networks that differ only in the touch response (and the touch afferent's
    weights) have the same ``walk_key`` and walk to an own-gait trip once
    (``WalkInCache``), each trip the same, bit for bit, as walked anew; a network that
    differs elsewhere has another key, and ``retouch`` refuses it."""
    from stumble.control.reflex.fit_walk import network_space, network_with
    from stumble.control.reflex.identify import default_network
    from stumble.pipeline import WalkInCache

    base = default_network("placement-es").with_touch().with_touch_response()
    space = network_space(base, touch_only=True, touch_response=True)
    rng = np.random.default_rng(5)
    a, b = (network_with(base, np.clip(space.start + space.scale * rng.normal(
        0, 1, len(space.names)), space.lo, space.hi), space.names) for _ in range(2))
    ka, kb = ReflexController(a).walk_key(), ReflexController(b).walk_key()
    assert ka == kb
    other = network_with(base, network_space(base, False).start * 1.01)
    assert ReflexController(other).walk_key() != ka
    with pytest.raises(ValueError, match="differ in more than"):
        ReflexController(a).retouch(other)
    sc = Scenario(controller="reflex", mechanism="obstacle", swing_fraction=0.15,
                  speed_m_per_s=1.2, start="own", duration_after_trip_s=0.5)
    cache = WalkInCache()
    for net in (a, b):
        cached = simulate_trip(sc, network=net, walk_in_cache=cache).recording
        fresh = simulate_trip(sc, network=net).recording
        assert np.array_equal(cached.qpos, fresh.qpos)
    assert len(cache) == 1
    assert not np.array_equal(simulate_trip(sc, network=a).recording.qpos,
                              simulate_trip(sc, network=b).recording.qpos)


def test_a_response_by_foot_answers_a_late_swing_touch_with_its_ahead_sets():
    """``TouchResponse.by_foot``: with gains only in the ``*_ahead`` sets, a trip early in
    swing (the tripped foot behind the other) runs as without a response, bit for bit,
    and one late in swing (the foot ahead) does not."""
    from stumble.control.reflex.fit_walk import network_space, network_with
    from stumble.control.reflex.identify import default_network

    net = default_network("placement-es")
    by_foot = net.with_touch_response(by_foot=True)
    space = network_space(by_foot, touch_only=True, touch_response=True)
    assert len(space.names) == 6 * 8 + 2
    theta = np.where([n.startswith("resp_") and "_ahead_" in n for n in space.names], 0.5,
                     space.start)
    ahead_only = network_with(by_foot, theta, space.names)
    for swing, same in ((0.13, True), (0.6, False)):
        sc = Scenario(controller="reflex", start="playback", mechanism="obstacle",
                      swing_fraction=swing, speed_m_per_s=1.2, duration_after_trip_s=0.5)
        plain = simulate_trip(sc, network=net).recording.qpos
        resp = simulate_trip(sc, network=ahead_only).recording.qpos
        assert (plain.shape == resp.shape and np.array_equal(plain, resp)) == same, swing


def _batch_net(hidden: int):
    """The default network, or a random one of its topology with ``hidden`` units."""
    from dataclasses import replace

    from stumble.control.reflex.identify import default_network
    from stumble.control.reflex.network import Network

    net = default_network("placement-both")
    if hidden == net.topology.hidden:
        return net
    top = replace(net.topology, hidden=hidden)
    out = Network.initial(top, net.mean, net.std, seed=hidden)
    out.b = np.random.default_rng(1).normal(0.0, 0.5, out.b.shape)
    out.c = np.random.default_rng(2).normal(0.0, 0.5, out.c.shape)
    return out


@pytest.mark.parametrize("code", ["numpy", "compiled", "compiled-then-numpy"])
@pytest.mark.parametrize("T", [1500, 7])
@pytest.mark.parametrize("hidden", [6, 3])
def test_the_networks_batch_pass_is_np_roll_s_bit_for_bit(code, T, hidden):
    """``Network.forward`` and ``gradient_z`` shift each path's units in place, in NumPy
    or in the compiled ``batch_z`` and ``batch_dh`` (for speed in DAgger's training and
    the identification): the numbers of the np.roll formulation, bit for bit, so that
    the shipped fits re-run to their files; a compiled forward's cache also serves the
    NumPy gradient. (T = 7: lags longer than twice the data wrap more than once.)"""
    from stumble.control.reflex import kernels

    if code != "numpy" and kernels.kernels() is None:
        pytest.skip("Numba is not installed")
    net = _batch_net(hidden)
    rng = np.random.default_rng(3)
    xd = rng.standard_normal((T, net.w.shape[0]))
    dz = rng.standard_normal((T, net.c.shape[0]))
    kernels.use_numpy(code == "numpy")
    try:
        u, cache = net.forward(xd)
        kernels.use_numpy(code != "compiled")
        grad = net.gradient_z(xd, dz, cache)
    finally:
        kernels.use_numpy(False)
    assert ("hd" in cache) == (code == "numpy")
    # the formulation before (np.roll of each path's units)
    h = np.tanh(xd @ net.w + net.b)
    units = net.units_of()
    conns = net.topology.connections()
    hd = np.stack([np.roll(h[:, units[k]], lag, axis=0)
                   for k, (_s, _j, lag) in enumerate(conns)], axis=1)
    if code == "numpy":
        assert np.array_equal(cache["hd"], hd)
    z = np.zeros((T, net.topology.n_muscles))
    contrib = np.einsum("tch,ch->tc", hd, net.v)
    for k, (_s, j, _lag) in enumerate(conns):
        z[:, j] += contrib[:, k]
    z += net.c
    assert np.array_equal(u, 1.0 / (1.0 + np.exp(-z)))
    js = np.array([j for _s, j, _lag in conns])
    dcontrib = dz[:, js]
    dv = np.einsum("tc,tch->ch", dcontrib, hd)
    dhd = dcontrib[:, :, None] * net.v[None]
    dh = np.zeros_like(h)
    for k, (_s, _j, lag) in enumerate(conns):
        dh[:, units[k]] += np.roll(dhd[:, k], -lag, axis=0)
    dpre = dh * (1.0 - h ** 2)
    mask = net._mask(net.topology)
    ref = np.concatenate([((xd.T @ dpre) * mask)[mask.astype(bool)], dpre.sum(axis=0),
                          dv.ravel(), dz.sum(axis=0)])
    assert np.array_equal(grad, ref)
    assert len({lag for *_x, lag in conns}) > 3  # (paths of several delays)
    assert T > 100 or max(lag for *_x, lag in conns) > 2 * T
