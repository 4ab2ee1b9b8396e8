"""The ``stumble`` command line: outputs later issues rely on, and one-line errors."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stumble.cli import main

REFERENCE = Path(__file__).resolve().parents[3] / "shared" / "reference"


def run(*args: str) -> subprocess.CompletedProcess:
    """The installed command, as a user runs it."""
    return subprocess.run([sys.executable, "-m", "stumble.cli", *args], capture_output=True,
                          text=True, timeout=300)


def test_version_and_help():
    r = run("--version")
    assert r.returncode == 0 and r.stdout.startswith("stumble ")
    r = run("--help")
    assert r.returncode == 0 and "walk" in r.stdout and "model" in r.stdout


@pytest.mark.parametrize("planar", [False, True])
def test_model_json(planar, capsys):
    assert main(["model", "--json", *(["--planar"] if planar else [])]) == 0
    d = json.loads(capsys.readouterr().out)
    for key in ("nq", "nv", "nu", "dof", "joints", "mass_kg", "segments"):
        assert key in d
    assert d["dof"] == (10 if planar else 42)
    assert d["mass_kg"] == pytest.approx(70.0)
    assert sum(d["segments"].values()) == pytest.approx(70.0)


def test_model_json_scales_with_mass_height_and_sex(capsys):
    main(["model", "--json", "--mass", "90", "--height", "1.9", "--sex", "female"])
    d = json.loads(capsys.readouterr().out)
    assert d["mass_kg"] == pytest.approx(90.0)
    assert d["height_m"] == 1.9 and d["sex"] == "female"


def _strict_json(path):
    return json.loads(path.read_text(), parse_constant=lambda c: pytest.fail(f"{path}: {c}"))


def test_walk_writes_the_named_files(tmp_path, capsys):
    out = tmp_path / "walk"
    assert main(["walk", "--out", str(out), "--no-video", "--duration", "3"]) == 0
    for name in ("motion.csv", "motion.mot", "motion.bvh", "events.json", "joint_angles.png"):
        assert (out / name).stat().st_size > 0
    assert (out / "motion.mot").read_text().startswith("stumble motion (gait2392 coordinates)")
    with (out / "motion.csv").open() as f:
        rows = list(csv.reader(f))
    header = rows[0]
    assert header[:4] == ["time_s", "pelvis_x_m", "pelvis_y_m", "pelvis_z_m"]
    assert "knee_angle_r_deg" in header and "hip_flexion_l_deg" in header
    data = np.array(rows[1:], dtype=float)
    assert data[-1, 0] == pytest.approx(3.0)
    knee = data[:, header.index("knee_angle_r_deg")]
    assert knee.min() < -60 and knee.max() < 5  # degrees at the edge
    ev = _strict_json(out / "events.json")
    assert ev["notes"] == []
    for side in ("r", "l"):
        assert ev[side]["toe_off_s"] and ev[side]["heel_strike_s"]
    assert ev["speed_m_per_s"] == pytest.approx(1.10, abs=0.03)
    assert ev["stance_fraction"] == pytest.approx(0.63, abs=0.05)
    assert ev["stride_s"] > 1.0


def test_walk_at_a_requested_speed_changes_cadence(tmp_path):
    main(["walk", "--out", str(tmp_path / "a"), "--no-video", "--speed", "0.8"])
    main(["walk", "--out", str(tmp_path / "b"), "--no-video", "--speed", "1.5"])
    slow = json.loads((tmp_path / "a" / "events.json").read_text())
    fast = json.loads((tmp_path / "b" / "events.json").read_text())
    assert fast["stride_s"] < slow["stride_s"]
    assert fast["speed_m_per_s"] == pytest.approx(1.5)


@pytest.mark.skipif(not REFERENCE.is_dir(), reason="shared/reference is not present")
def test_walk_plays_the_subject01_mot_without_options(tmp_path):
    mot = REFERENCE / "walking" / "subject01_walk1_ik.mot"
    r = run("walk", "--out", str(tmp_path), "--gait", str(mot), "--no-video")
    assert r.returncode == 0, r.stderr
    ev = _strict_json(tmp_path / "events.json")  # 1.2 s, less than two strides: no NaN
    assert ev["source"] == "file: subject01_walk1_ik.mot"
    assert len(ev["r"]["toe_off_s"]) + len(ev["l"]["toe_off_s"]) >= 1
    assert ev["stride_s"] == pytest.approx(1.23, abs=0.03)
    assert 0.55 < ev["stance_fraction"] < 0.7
    assert ev["notes"][0].startswith("subject01_walk1_ik.mot: no complete stride of one foot")
    assert r.stderr.startswith("stumble: note: subject01_walk1_ik.mot: no complete stride")
    # .mot -> stumble -> .mot: every coordinate within 0.01 deg with --as-recorded
    out = tmp_path / "exact"
    r = run("walk", "--out", str(out), "--gait", str(mot), "--no-video", "--as-recorded")
    assert r.returncode == 0, r.stderr
    assert _max_angle_change(mot, out / "motion.mot") < 0.01


def _max_angle_change(before, after) -> float:
    """Largest difference (deg) of any rotational coordinate of ``before`` in ``after``."""
    from stumble.gait.readers import read_mot

    a, b = read_mot(before), read_mot(after)
    np.testing.assert_allclose(b.time_s, a.time_s - a.time_s[0], atol=1e-9)
    worst = 0.0
    for k, v in a.columns.items():
        if k.startswith("pelvis_t") and k != "pelvis_tilt":
            continue  # translations: placed by stumble on its own body
        worst = max(worst, float(np.degrees(np.abs(b.columns[k] - v).max())))
    return worst


def test_mot_round_trip_keeps_every_coordinate(tmp_path):
    from stumble.gait.readers import write_storage
    from stumble.gait.reference import load_reference
    from stumble.gait.writers import GAIT2392_COORDINATES

    gait = load_reference()
    t = np.arange(0.0, 2.5, 1 / 60)
    cols = gait.angles(t / gait.stride_s + 0.3)
    cols.update({"pelvis_list": np.radians(3.0) * np.sin(t), "pelvis_rotation":
                 np.radians(5.0) * np.cos(t), "pelvis_tx": 1.1 * t, "pelvis_ty": 0.95 + 0 * t,
                 "pelvis_tz": 0 * t, "subtalar_angle_r": np.radians(4.0) * np.sin(3 * t),
                 "mtp_angle_l": np.radians(10.0) * np.sin(2 * t)})
    cols = {k: cols.get(k, 0 * t) for k in GAIT2392_COORDINATES}
    src = tmp_path / "in.mot"
    write_storage(src, t, cols)
    out = tmp_path / "o"
    assert main(["walk", "--gait", str(src), "--as-recorded", "--no-video", "--out",
                 str(out)]) == 0
    assert _max_angle_change(src, out / "motion.mot") < 0.01


def test_bvh_round_trip_keeps_the_legs(tmp_path):
    from stumble.gait.bvh import bvh_to_coordinates, read_bvh
    from stumble.gait.bvh_test import _bvh_text, _walk_frames

    src = tmp_path / "in.bvh"
    src.write_text(_bvh_text(_walk_frames(n=100), dt=1 / 30))
    out = tmp_path / "o"
    assert main(["walk", "--gait", str(src), "--as-recorded", "--no-video", "--out",
                 str(out)]) == 0
    a = bvh_to_coordinates(read_bvh(src))
    b = bvh_to_coordinates(read_bvh(out / "motion.bvh"))
    for side in "rl":
        for j in ("hip_flexion", "hip_adduction", "hip_rotation", "knee_angle",
                  "ankle_angle"):
            k = f"{j}_{side}"
            assert np.degrees(np.abs(b.columns[k] - a.columns[k]).max()) < 0.5, k


def _one_line_error(r: subprocess.CompletedProcess, *words: str) -> None:
    assert r.returncode != 0
    err = r.stderr.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err


@pytest.mark.parametrize(("args", "words"), [
    (["model", "--height", "-1.75"], ["height"]),
    (["model", "--height", "2.9"], ["height"]),
    (["model", "--mass", "abc"], ["mass"]),
    (["walk", "--out", "OUT", "--speed", "2.5"], ["speed", "2.5"]),
    (["walk", "--out", "OUT", "--speed", "0.2"], ["speed"]),
    (["walk", "--out", "OUT", "--gait", "missing.mot"], ["missing.mot"]),
    (["reflex", "fit", "--controller", "gh2010", "--trip-set", "wide", "--out", "OUT"],
     ["--trip-set is for --trips"]),
    (["reflex", "fit", "--controller", "gh2010", "--scr-phase", "foot", "--out", "OUT"],
     ["--scr-phase is for --trips"]),
    (["reflex", "fit", "--scr-phase", "foot", "--out", "OUT"], ["--controller gh2010"]),
    (["reflex", "fit", "--ta-bound", "paper", "--out", "OUT"], ["--controller gh2010"]),
    (["reflex", "fit", "--stance-weight", "20", "--out", "OUT"], ["--controller gh2010"]),
    (["reflex", "fit", "--controller", "gh2010", "--touch-only", "--out", "OUT"],
     ["--touch-only is for --trips"]),
    (["reflex", "fit", "--touch-only", "--out", "OUT"], ["--controller gh2010"]),
    (["reflex", "fit", "--controller", "gh2010", "--recovery-cost", "5", "--out", "OUT"],
     ["--recovery-cost is for --trips"]),
    (["reflex", "fit", "--controller", "gh2010", "--trips", "--recovery-cost", "-2", "--out",
      "OUT"], ["--recovery-cost: must be a number in 0-10000", "-2"]),
    (["reflex", "fit", "--controller", "gh2010", "--trips", "--recovery-cost", "nan",
      "--out", "OUT"], ["--recovery-cost: must be a number in 0-10000"]),
    (["reflex", "fit", "--recovery-cost", "5", "--out", "OUT"], ["--controller gh2010"]),
    (["reflex", "fit", "--controller", "gh2010", "--trips", "--touch-only", "--placement",
      "--out", "OUT"], ["--placement", "--touch-only"]),
    (["reflex", "fit", "--placement", "--out", "OUT"], ["--controller gh2010"]),
    (["reflex", "fit", "--controller", "gh2010", "--stance-weight", "-2", "--out", "OUT"],
     ["--stance-weight", "-2"]),
    (["reflex", "fit", "--controller", "gh2010", "--stance-weight", "nan", "--out", "OUT"],
     ["--stance-weight", "nan"]),
    (["reflex", "fit", "--knee-weight", "2", "--out", "OUT"], ["--controller gh2010"]),
    (["reflex", "fit", "--controller", "gh2010", "--knee-weight", "-1", "--out", "OUT"],
     ["--knee-weight: must be a number in 0-10000", "-1"]),
    (["reflex", "fit", "--controller", "gh2010", "--trips", "--touch-only", "--knee-weight",
      "2", "--out", "OUT"], ["--knee-weight", "--touch-only"]),
    (["reflex", "fit", "--walk-es", "placement-both", "--cross-step", "--out", "OUT"],
     ["--cross-step is for --controller network --walk-es --touch-response"]),
    (["reflex", "fit", "--walk-es", "placement-both", "--touch-only", "--touch-response",
      "--trip-set", "dense", "--cross-only", "--out", "OUT"],
     ["--cross-only is for --touch-only --cross-step"]),
    (["reflex", "fit", "--controller", "gh2010", "--trips", "--trip-set", "pool", "--out",
      "OUT"], ["--trip-set pool", "is for --controller network --walk-es --trip-sample"]),
    (["reflex", "fit", "--trip-sample", "5", "--out", "OUT"],
     ["--trip-sample is for --controller network --walk-es --trip-set"]),
    (["reflex", "fit", "--walk-es", "placement-both", "--touch-only", "--touch-response",
      "--trip-set", "dense", "--trip-sample", "31", "--out", "OUT"],
     ["--trip-sample must be 1-30", "31"]),
    (["reflex", "fit", "--ahead-from", "placement-foot", "--out", "OUT"],
     ["--ahead-from is for --controller network --walk-es"]),
    (["reflex", "fit", "--walk-es", "placement-touch", "--touch-only", "--touch-response",
      "--trip-set", "dense", "--ahead-from", "placement-foot", "--out", "OUT"],
     ["--ahead-from is for --touch-response --scr-phase foot"]),
    (["reflex", "fit", "--walk-es", "placement-touch", "--touch-only", "--touch-response",
      "--scr-phase", "foot", "--trip-set", "dense", "--ahead-from", "closed-loop", "--out",
      "OUT"], ["--ahead-from: that network has no touch response by the foot"]),
    (["study", "--out", "OUT", "--params", "missing.json"],
     ["missing.json: no such file, nor a shipped state-machine set (flight, upright, "
      "step, anderson2007_walk_on, anderson2007, hip_cap, knee_cap, flight_from_fall, "
      "rec_hip_cap, sup_hip_cap)"]),
    (["study", "--out", "OUT", "--controller", "reflex", "--params", "anderson2007"],
     ["--params is for --controller fsm"]),
])
def test_bad_input_is_one_line_and_non_zero(tmp_path, args, words):
    args = [str(tmp_path / "o") if a == "OUT" else a for a in args]
    _one_line_error(run(*args), *words)


@pytest.mark.parametrize(("text", "words"), [
    ('{"params": {}, "settings": {"trunk_attitude": -0.3}}', "trunk_attitude = -0.3 is not"),
    ('{"params": {"kp_knee": 5000}}', "kp_knee = 5000 is outside 100-800"),
    ('{"params": {}, "settings": {"trunk": 1}}', "unknown setting 'trunk'"),
])
@pytest.mark.parametrize("command", ["study", "trip"])
def test_a_bad_params_file_is_one_line_naming_it(tmp_path, text, words, command):
    bad = tmp_path / "bad-params.json"
    bad.write_text(text)
    r = run(command, "--out", str(tmp_path / "o"), "--params", str(bad))
    _one_line_error(r, f"{bad}: {words}")
    assert not (tmp_path / "o").exists()


def test_pipes_devices_and_absurd_files_are_one_line_errors(tmp_path):
    import os

    fifo = tmp_path / "pipe.mot"
    os.mkfifo(fifo)
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(fifo)),
                    "pipe.mot: not a regular file")
    if Path("/dev/zero").exists():
        _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", "/dev/zero"),
                        "zero: not a regular file")
    one = tmp_path / "one.mot"
    one.write_text("Coordinates\nendheader\ntime\tknee_angle_r\n0\t-10\n")
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(one)),
                    "one.mot: 1 data row(s); at least 2 are needed")
    from stumble.gait.bvh_test import _bvh_text

    frame = tmp_path / "frame.bvh"
    frame.write_text(_bvh_text([{}]))
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(frame)),
                    "frame.bvh: 1 sample(s)")
    ms = tmp_path / "ms.mot"
    rows = "".join(f"{k * 100}\t{-30 - 20 * np.sin(k / 2):.2f}\n"  # 10 Hz, time in ms
                   for k in range(30001))
    ms.write_text("Coordinates\nendheader\ntime\tknee_angle_r\n" + rows)
    r = run("walk", "--out", str(tmp_path / "o"), "--gait", str(ms), "--no-video")
    _one_line_error(r, "ms.mot: lasts 3000 s; stumble plays at most 600 s")
    assert not (tmp_path / "o").exists()


def test_corrupt_and_unknown_files_are_one_line_errors(tmp_path):
    bad = tmp_path / "corrupt.mot"
    bad.write_text("Coordinates\nversion=1\nendheader\ntime\tknee_angle_r\n0.0\tabc\n")
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(bad)),
                    "corrupt.mot")
    arms = tmp_path / "arms.mot"
    arms.write_text("Coordinates\nversion=1\ninDegrees=yes\nendheader\n"
                    "time\tr_shoulder_elev\twing_flap\n0.0\t-10\t3\n0.01\t-11\t4\n")
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(arms)),
                    "arms.mot: no hip, knee or ankle coordinate", "wing_flap")
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(bad),
                        "--speed", "1.0"), "--speed")


def _main_error(capsys, argv) -> str:
    """Run ``stumble argv``; assert exit 2 and one line on stderr; return that line."""
    try:
        code = main(argv)
    except SystemExit as e:  # argparse's own checks
        code = e.code
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("stumble: ") and err.count("\n") == 1, err
    return err


@pytest.fixture
def no_simulation(monkeypatch):
    """Any trip or fit simulated fails the test: the error must come first."""
    import stumble.control.reflex.identify as identify
    import stumble.pipeline as pipeline

    def boom(*a, **k):
        raise AssertionError("simulated before the error")

    monkeypatch.setattr(pipeline, "simulate_trip", boom)
    monkeypatch.setattr(identify, "fit", boom)


@pytest.mark.parametrize("argv, words", [
    (["trip", "--seed", "-1"], "argument --seed: must be from 0 to 9223372036854775807"),
    (["trip", "--seed", str(2**63)], "must be from 0 to"),
    (["trip", "--seed", "1.5"], "argument --seed: '1.5' is not a whole number"),
    (["reflex", "fit", "--seed", "-3"], "argument --seed: must be from 0"),
])
def test_bad_seeds_are_one_line(tmp_path, capsys, no_simulation, argv, words):
    assert words in _main_error(capsys, [*argv, "--out", str(tmp_path / "o")])
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", [["walk"], ["trip"], ["reflex", "fit"], ["study"],
                                     ["validate"]])
def test_an_empty_out_is_one_line(tmp_path, capsys, monkeypatch, no_simulation, command):
    monkeypatch.chdir(tmp_path)
    assert "the output directory is empty" in _main_error(capsys, [*command, "--out", ""])
    assert list(tmp_path.iterdir()) == []  # nothing written into the current directory


def _unwritable(tmp_path) -> Path:
    if os.geteuid() == 0:  # root writes through mode bits: /proc refuses anyone
        return Path("/proc")
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    return d


@pytest.mark.parametrize("command", [["walk", "--no-video"], ["trip", "--no-video"],
                                     ["reflex", "fit"]])
def test_an_unwritable_out_is_found_before_any_simulation(tmp_path, capsys, no_simulation,
                                                          command):
    out = _unwritable(tmp_path)
    err = _main_error(capsys, [*command, "--out", str(out)])
    assert f"output directory {out} is not writable" in err


def test_trip_population_and_strength_options(tmp_path, capsys):
    err = _main_error(capsys, ["trip", "--out", str(tmp_path / "a"), "--controller", "gh2010",
                               "--population", "older"])
    assert "population older is defined for the state machines" in err
    out = tmp_path / "b"
    assert main(["trip", "--out", str(out), "--population", "older", "--strength",
                 "anderson2007", "--duration", "0.5", "--no-video"]) == 0
    s = json.loads((out / "summary.json").read_text())
    # the older preset's preferred speed (Tirosh & Sparrow 2004) when --speed is not given
    assert s["speed_m_per_s"] == 1.17 and s["population"] == "older"
    assert s["strength_model"] == "anderson2007"
    assert s["support_peak_moments_nm"]["ankle_plantarflexion"] > 0.0
    # the set that ran is named: the default for human strength walking on
    from stumble.control.fsm_params import read_params

    assert s["fsm_params"] == {"path": "anderson2007_walk_on", "default": True,
                               "sha256": read_params("anderson2007_walk_on").sha256}


def test_trip_names_the_state_machine_set_it_ran(tmp_path):
    """summary.json's ``fsm_params``: the shipped set or file that ran, its SHA-256, and
    whether it was the default (``rec_hip_cap`` since 2026-12-07)."""
    from stumble.control.fsm_params import DEFAULT_SET, read_params

    argv = ["trip", "--duration", "0.5", "--no-video"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert DEFAULT_SET == "rec_hip_cap"
    assert s["fsm_params"] == {"path": "rec_hip_cap", "default": True,
                               "sha256": read_params("rec_hip_cap").sha256}
    f = tmp_path / "flight.json"
    f.write_bytes(read_params("flight").path.read_bytes())
    assert main([*argv, "--out", str(tmp_path / "b"), "--params", str(f)]) == 0
    s = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert s["fsm_params"] == {"path": str(f), "default": False,
                               "sha256": read_params("flight").sha256}


def test_the_help_names_every_shipped_gh2010_set_and_the_default():
    """``--params`` of ``trip``, ``reflex walk`` and ``reflex fit`` lists ``gh2010.NAMED``
    (kept as text in the CLI, so that it starts without importing the physics)."""
    from stumble.cli import GH2010_NAMES
    from stumble.control.reflex.gh2010 import NAMED, SHIPPED

    assert all(name in GH2010_NAMES for name in NAMED)
    default = next(n for n, f in NAMED.items() if f == SHIPPED["gh2010"])
    assert f"{default} (the default" in GH2010_NAMES
    r = run("reflex", "walk", "--help")
    assert r.returncode == 0 and f"{default} (the default" in " ".join(r.stdout.split())


def test_options_that_would_be_ignored_are_refused(tmp_path, capsys):
    """An option that does not apply to the run is one line, not silently ignored: the
    obstacle's height on a force trip, the reference's alignment without a reference,
    BVH axes on another format, an OpenSim model family on a BVH file."""
    mot, bvh = tmp_path / "w.mot", tmp_path / "w.bvh"
    mot.write_text("x")  # the options are refused before the file is read
    bvh.write_text("x")
    out = str(tmp_path / "o")
    for argv, says in (
            (["trip", "--obstacle-height", "0.1"], "--obstacle-height is for --mechanism obstacle"),
            (["trip", "--reference-align", "time"], "--reference-align applies to a --reference"),
            (["walk", "--gait", str(mot), "--up", "y"], "w.mot: --up and --forward are for .bvh"),
            (["walk", "--gait", str(mot), "--forward", "x"], "--up and --forward are for .bvh"),
            (["walk", "--gait", str(bvh), "--model", "gait2392"],
             "w.bvh: --model is for .mot and .sto files")):
        assert says in _main_error(capsys, [*argv, "--out", out, "--no-video"]), argv
    assert not (tmp_path / "o").exists()


def test_a_walk_too_short_to_write_names_the_option(tmp_path, capsys):
    """``walk --duration`` below a few frames: one line naming the option (it once named
    the motion.mot it could not write)."""
    err = _main_error(capsys, ["walk", "--out", str(tmp_path / "o"), "--duration", "1e-9",
                               "--no-video"])
    assert "--duration 1e-09 s is too short to write a motion (at least 0.05 s)" in err


def test_an_unknown_mujoco_gl_is_one_line_not_a_traceback(tmp_path):
    """MuJoCo raises at import under a MUJOCO_GL it does not know; stumble says so in one
    line and exits 2 before anything runs."""
    env = {**os.environ, "MUJOCO_GL": "bogus"}
    r = subprocess.run([sys.executable, "-c", "import sys; from stumble.cli import main; "
                        f"sys.exit(main(['walk', '--out', {str(tmp_path / 'w')!r}]))"],
                       env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.count("\n") == 1 and "MUJOCO_GL: bogus" in r.stderr
    assert not (tmp_path / "w").exists()


@pytest.mark.parametrize(("argv", "words"), [
    (["trip", "--strength-scale", "1.5", "--out", "x"],
     "unrecognized arguments: --strength-scale 1.5 (see `stumble trip --help`)"),
    (["reflex", "walk", "--out", "x", "--delays", "response"],
     "unrecognized arguments: --delays response (see `stumble reflex walk --help`)"),
])
def test_an_option_the_subcommand_lacks_points_to_its_own_help(argv, words, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1


def test_trip_says_when_a_walk_on_never_got_past_the_obstacle(tmp_path, capsys):
    """The network ``placement-both``'s lowering trip at 0.7 of swing (1.2 m/s) walks on
    3 s behind the box: the command says why it did not recover, and summary.json's stop
    reason names it."""
    out = tmp_path / "n"
    assert main(["trip", "--controller", "reflex", "--network", "placement-both",
                 "--mechanism", "obstacle", "--swing", "0.7", "--speed", "1.2", "--no-video",
                 "--out", str(out)]) == 0
    assert "did not recover: walking, but not past the obstacle" in capsys.readouterr().out
    s = json.loads((out / "summary.json").read_text())
    assert s["stop_reason"] == "not past the obstacle" and not s["recovered"]
