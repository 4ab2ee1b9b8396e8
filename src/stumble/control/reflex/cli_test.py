"""``stumble reflex fit`` and ``stumble trip --controller reflex`` as a user runs them."""

import csv
import json

import pytest

from stumble.cli import main


def test_reflex_fit_writes_its_files(tmp_path, capsys):
    out = tmp_path / "net"
    assert main(["reflex", "fit", "--out", str(out), "--iterations", "10",
                 "--refine", "20"]) == 0
    fit = json.loads((out / "fit.json").read_text())
    for key in ("avg_error", "max_error", "iterations", "wall_time_s"):
        assert key in fit
    assert fit["iterations"] == 30
    assert set(fit["walking_step"]["rmse_deg"]) >= {"hip_flexion_r", "knee_angle_l"}
    with (out / "walking_moments.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 51 and list(rows[0]) == ["percent", "hip_moment_nm",
                                                "knee_moment_nm", "ankle_moment_nm"]
    # the ankle's plantarflexor moment in late stance: about -1.6 N·m/kg × 70 kg
    assert min(float(r["ankle_moment_nm"]) for r in rows) < -80.0
    with (out / "walking_activity.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 51 and "SOL_network" in rows[0] and "HAMS_target" in rows[0]
    assert (out / "activity_fit.png").stat().st_size > 10_000
    assert (out / "network.npz").is_file()
    assert "identified" in capsys.readouterr().out


def test_reflex_trip_with_a_fitted_network(tmp_path):
    net = tmp_path / "net"
    main(["reflex", "fit", "--out", str(net), "--iterations", "5", "--refine", "5"])
    out = tmp_path / "trip"
    assert main(["trip", "--controller", "reflex", "--network", str(net / "network.npz"),
                 "--start", "playback", "--swing", "0.56", "--duration", "0.6", "--no-video",
                 "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["controller"] == "reflex" and s["mechanism"] == "obstacle"
    assert s["strategy"] in ("elevating", "lowering", None)
    assert (out / "muscle_tensions.png").stat().st_size > 10_000
    header = (out / "timeseries.csv").read_text().splitlines()[0]
    assert "knee_angle_l_deg" in header and "subtalar" not in header
    # OpenSim: the planar model's coordinates and the 14 muscles' activation and force
    from stumble.gait.readers import read_mot

    assert read_mot(out / "motion.mot").columns.keys() >= {"pelvis_tilt", "knee_angle_r",
                                                           "lumbar_extension"}
    sto = read_mot(out / "muscles.sto")
    act = [k for k in sto.columns if k.endswith("/activation")]
    assert len(act) == 14 and "/forceset/soleus_l/activation" in act
    for k in act:
        assert 0.0 <= sto.columns[k].min() and sto.columns[k].max() <= 1.0
    assert max(sto.columns["/forceset/soleus_r|tendon_force"]) > 100.0  # N


# a touch stage on past-foot whose --set-response each case below completes
_SET_RESPONSE = ["reflex", "fit", "--walk-es", "past-foot", "--touch-only", "--touch-response",
                 "--scr-phase", "foot", "--trip-set", "wide", "--set-response"]


@pytest.mark.parametrize("argv, message", [
    (["trip", "--controller", "reflex", "--strategy", "lowering"], "emerges"),
    (["trip", "--network", "x.npz"], "for --controller reflex"),
    (["trip", "--controller", "reflex", "--network", "missing.npz"], "does not exist"),
    (["reflex", "fit", "--iterations", "0", "--refine", "0"], "not both 0"),
    # DAgger and the identification have no generations: not silently ignored
    (["reflex", "fit", "--closed-loop", "--generations", "-3"],
     "--generations is for --controller gh2010 and --walk-es"),
    (["reflex", "fit", "--generations", "5"], "--generations is for --controller gh2010"),
    (["trip", "--start", "own"], "fsm controller does not walk on its own"),
    (["trip", "--controller", "reflex", "--start", "playback", "--walk-in", "3"],
     "--walk-in is for --start own"),
    (["trip", "--controller", "gh2010", "--walk-in", "1"], "walk-in 1.0 s is outside 2-30 s"),
    # options of the state machines' alone: refused, not recorded as if applied
    (["trip", "--controller", "reflex", "--strength", "anderson2007"],
     "strength model anderson2007 is for the state machines' servos"),
    (["trip", "--controller", "gh2010", "--recovery", "step"],
     "recovery rule step is for the state machines"),
    # the touch response's gains set by hand: named, within -1 to 1, with a response
    (["reflex", "fit", "--walk-es", "past-foot", "--touch-only", "--trip-set", "wide",
      "--set-response", "contra_ahead.HFL=1"], "--set-response is for --controller network "
     "--walk-es --touch-response"),
    *[([*_SET_RESPONSE, spec], words) for spec, words in (
        ("contra_ahead.HFL", "'contra_ahead.HFL' is not SET.MUSCLE=GAIN"),
        ("contra_ahead.HFL=nan", "'contra_ahead.HFL=nan' is not SET.MUSCLE=GAIN"),
        ("contra_ahead.HFL=1.5", "contra_ahead.HFL = 1.5 is not within -1 to 1"),
        ("swing.HFL=1", "the response has no set 'swing'"),
        ("contra.ILIO=1", "contra.ILIO: the network drives HAMS"),
        ("contra.HFL=1,contra.HFL=0", "contra.HFL is given twice"))],
    # a trip stage's trunk limit: network --walk-es with trips, 5-90 degrees
    (["reflex", "fit", "--walk-es", "past-swing", "--max-tilt", "26"],
     "--max-tilt needs --trip-set"),
    (["reflex", "fit", "--walk-es", "past-swing", "--trip-set", "wide", "--max-tilt", "26"],
     "--max-tilt needs --recovery-cost W > 0"),
    (["reflex", "fit", "--walk-es", "past-swing", "--trip-set", "wide", "--max-tilt", "nan"],
     "--max-tilt must be 5-90 degrees, got nan"),
    (["reflex", "fit", "--walk-es", "past-swing", "--trip-set", "wide", "--max-tilt", "2"],
     "--max-tilt must be 5-90 degrees, got 2.0"),
    (["reflex", "fit", "--controller", "gh2010", "--trips", "--max-tilt", "26"],
     "--max-tilt is for --controller network --walk-es --trip-set"),
])
def test_reflex_errors_are_one_line(tmp_path, capsys, argv, message):
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


@pytest.mark.parametrize("extra", [[], ["--closed-loop"], ["--controller", "gh2010"]])
@pytest.mark.parametrize("workers", ["0", "-1"])
def test_reflex_fit_workers_below_one_are_refused(tmp_path, capsys, extra, workers):
    """``reflex fit --workers`` below 1 is refused in one line by every fit (the
    identification ignored it and DAgger ran on one process)."""
    with pytest.raises(SystemExit) as e:
        main(["reflex", "fit", *extra, "--workers", workers, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert e.value.code == 2 and f"--workers: must be at least 1, got {workers}" in err
    assert err.count("\n") == 1 and not (tmp_path / "o").exists()


@pytest.mark.parametrize("make, words", [
    (lambda p: p.write_text("w = 1\n"), "not a zip archive"),
    (lambda p: p.mkdir(), "is a directory, not a network file"),
    (lambda p: p.write_bytes(b"PK\x03\x04" + bytes(100)), "not a readable network .npz"),
])
def test_a_bad_network_file_is_one_line_before_the_trip(tmp_path, capsys, monkeypatch, make,
                                                        words):
    import stumble.pipeline as pipeline

    monkeypatch.setattr(pipeline, "simulate_trip", lambda *a, **k: 1 / 0)
    path = tmp_path / "net.npz"
    make(path)
    assert main(["trip", "--controller", "reflex", "--network", str(path), "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert words in err and str(path) in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


def test_a_network_whose_tick_the_time_step_does_not_divide(tmp_path, capsys):
    from stumble.control.reflex.identify import default_network
    from stumble.control.reflex.network import Network, Topology

    t = default_network("open-loop").topology
    n = default_network("open-loop")
    # the default 2 ms step is neither a divisor nor a whole number of a 0.833 ms tick
    fast = Network(Topology(1200.0, t.hidden, t.contact), n.w, n.b, n.v, n.c, n.mean, n.std,
                   n.info, n.walk_rates)
    fast.save(tmp_path / "fast.npz")
    assert main(["trip", "--controller", "reflex", "--network", str(tmp_path / "fast.npz"),
                 "--out", str(tmp_path / "o")]) == 2
    assert ("ticks every 0.833333 ms: the time step (2 ms) must divide it or be a whole "
            "number of ticks") in capsys.readouterr().err


def test_a_gh2010_trip_in_its_own_gait_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "own"
    assert main(["trip", "--controller", "gh2010", "--swing", "0.13", "--walk-in", "2.5",
                 "--duration", "1", "--no-video", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["start"] == "own" and s["strategy"] == "elevating"
    assert s["walk_in"]["toe_off_s"] >= 2.5 and 1.0 <= s["walk_in"]["stride_s"] <= 1.4
    assert "elevating strategy" in capsys.readouterr().out


def test_a_2ms_gh2010_set_trips_at_its_own_step_from_the_command_line(tmp_path):
    """``stumble trip --controller gh2010 --params knee-2ms`` runs at the 2 ms the set was
    fitted at, as ``simulate_trip`` does (until 2026-12-05 the command line resolved the
    step before loading the set, and ran it at 1 ms), and recovers as docs/gh2010.md says."""
    out = tmp_path / "t"
    assert main(["trip", "--controller", "gh2010", "--params", "knee-2ms", "--swing", "0.1",
                 "--speed", "1.2", "--no-video", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["steps"] == 1500  # 3 s after the trip in 2 ms steps
    assert s["strategy"] == "elevating" and s["recovered"]


def test_the_closed_loop_network_tripped_in_its_own_gait_writes_uniform_motion(tmp_path):
    """Its 17 ms blocks put the trip off the 5 ms sample grid of its walk: the walk shown
    before the trip is resampled, so motion.bvh (uniform frames) is written."""
    out = tmp_path / "net"
    assert main(["trip", "--controller", "reflex", "--network", "closed-loop", "--start",
                 "own", "--walk-in", "2", "--swing", "0.15", "--duration", "0.5",
                 "--no-video", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["start"] == "own" and s["walk_in"]["toe_off_s"] >= 2.0
    from stumble.gait.bvh import read_bvh

    bvh = read_bvh(out / "motion.bvh")
    assert bvh.frame_time_s > 0 and bvh.n_frames > 100


@pytest.mark.parametrize("flag", ["--recovery-cost", "--strategy-cost", "--track-weight",
                                  "--knee-weight", "--stance-weight", "--foot-angle"])
def test_an_objective_weight_past_its_range_is_refused(tmp_path, capsys, flag):
    """An objective's weight of 1e308 made every cost infinite (a fit of nothing, its
    history all null): refused in one line, as NaN and negative weights are."""
    for bad in ("1e308", "-1", "nan"):
        with pytest.raises(SystemExit) as e:
            main(["reflex", "fit", "--controller", "gh2010", "--trips", f"{flag}={bad}",
                  "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err
        assert e.value.code == 2 and f"argument {flag}: must be a number in 0-10000" in err
    assert not (tmp_path / "o").exists()
