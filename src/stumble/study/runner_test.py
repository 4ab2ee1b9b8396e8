"""Studies: the crash-safe store, resumption, error rows, the default sets recorded,
executors (in process, local processes, Dask), plots, and real trips through the CLI."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from types import SimpleNamespace

import pyarrow.parquet as pq
import pytest

from stumble import pipeline
from stumble.cli import main
from stumble.errors import InputError, StumbleError
from stumble.study import runner
from stumble.study.grid import Grid, load_toml, parse_values, run_key
from stumble.study.runner import StudyInterrupted, flatten, outcome, run_study, summary_table
from stumble.study.store import Store, load_results
from stumble.trip import Scenario

WALL = {"wall_time_s", "run_wall_time_s", "checksum"}  # the only columns allowed to differ


def fake_summary(sc: Scenario) -> dict:
    """A deterministic stand-in for ``simulate_trip(sc).summary``."""
    strategy = sc.strategy if sc.strategy != "auto" else (
        "elevating" if sc.swing_fraction <= 0.5 else "lowering")
    fell = sc.delay_scale * sc.swing_fraction >= 0.6
    return {"controller": sc.controller, "strategy": strategy, "variant": "double_support",
            "recovered": not fell, "fell": fell, "diverged": False,
            "swing_fraction": sc.swing_fraction, "speed_m_per_s": sc.speed_m_per_s,
            "mechanism": sc.mechanism, "leg": sc.leg, "obstacle_height_m": None,
            "states": [{"name": "passive_reaction", "start_s": 0.0}],
            "durations_s": {"recovery_step": round(0.5 + sc.swing_fraction, 4),
                            "trip_to_recovery_contact": 0.6},
            "rmse_deg": None, "wall_time_s": 0.001, "steps": 10, "seed": sc.seed}


@pytest.fixture
def fake(monkeypatch):
    """simulate_trip replaced: reflex raises, swing 0.85 diverges; the calls are listed."""
    calls: list[Scenario] = []

    def simulate_trip(sc, **kw):
        calls.append(sc)
        if sc.controller == "reflex":
            raise InputError("controller 'reflex' is not available (fsm)")
        if sc.swing_fraction == 0.85:  # as sim.run reports it: a summary, not a raise
            return SimpleNamespace(summary={**fake_summary(sc), "diverged": True,
                                            "recovered": False, "fell": False,
                                            "stop_reason": "diverged"})
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", simulate_trip)
    return calls


def rows_of(path: Path) -> list[dict]:
    return pq.read_table(path).to_pylist()


def strip(rows):
    return [{k: v for k, v in r.items() if k not in WALL} for r in rows]


# ---------------------------------------------------------------- parsing


@pytest.mark.parametrize("args, words", [
    (["--swing", "0.05:0.95:3"], "swing fraction 0.95 is outside 0.05-0.9"),
    (["--speed", "0.8,2.0"], "speed 2.0 m/s is outside"),
    (["--controller", "fsm,pid"], "controller 'pid' is not one of fsm, reflex"),
    (["--mechanism", "slip"], "mechanism 'slip'"),
    (["--height", "3"], "height 3.0 m is outside"),
    (["--delay-scale", "0.1:2:3"], "delay scale 0.1 is outside"),
    (["--seed", "1", "--repeats", "3"], "give one, not both"),
    (["--repeats", "0"], "--repeats: 0 is outside"),
    (["--workers", "0"], "argument --workers: must be at least 1, got 0"),
])
def test_bad_grid_is_one_line_before_anything_runs(tmp_path, capsys, fake, args, words):
    out = tmp_path / "s"
    try:
        code = main(["study", "--out", str(out), *args])
    except SystemExit as e:  # argparse's own checks
        code = e.code
    assert code == 2
    err = capsys.readouterr().err
    assert words in err and err.startswith("stumble: ") and err.count("\n") == 1
    assert not out.exists() and not fake


def test_flatten_nested_and_lists():
    d = flatten({"a": 1, "durations_s": {"x": 0.5, "y": None},
                 "states": [{"name": "s", "start_s": 0.0}]})
    assert d == {"a": 1, "durations_s.x": 0.5, "durations_s.y": None,
                 "states": '[{"name": "s", "start_s": 0.0}]'}


# ---------------------------------------------------------------- running (fake trips)


def small_grid(**axes) -> list[Scenario]:
    base = {"swing": [0.2, 0.4, 0.6, 0.85], "speed": [1.0, 1.3]}
    return Grid({**base, **axes}).scenarios()


def test_study_rows_table_and_rerun(tmp_path, fake, capsys):
    out = tmp_path / "s"
    res = run_study(small_grid(), out, workers=1, progress=False)
    assert len(fake) == 8 and res.ran == 8 and res.before == 0
    rows = rows_of(out / "results.parquet")
    assert len(rows) == 8 and [r["key"] for r in rows] == [r["key"] for r in res.rows]
    r = rows[0]
    # every scenario parameter and every summary field, nested ones flattened
    for col in ("swing_fraction", "speed_m_per_s", "leg", "mechanism", "obstacle_height_m",
                "controller", "strategy_mode", "seed", "height_m", "mass_kg", "sex",
                "contact", "duration_after_trip_s", "delay_scale", "delays", "strength_scale",
                "timestep_s", "strategy", "variant", "recovered", "fell", "diverged",
                "durations_s.recovery_step", "durations_s.trip_to_recovery_contact",
                "states", "steps", "error", "key", "stumble_version"):
        assert col in r, col
    assert json.loads(r["states"]) == [{"name": "passive_reaction", "start_s": 0.0}]
    assert r["durations_s.recovery_step"] == pytest.approx(0.7)
    assert r["obstacle_height_m"] is None  # a force trip
    div = [r for r in rows if r["swing_fraction"] == 0.85]
    assert div and all(r["diverged"] and r["error"] is None and outcome(r) == "diverged"
                       for r in div)
    # the same study again: nothing to run, same table
    fake.clear()
    res2 = run_study(small_grid(), out, workers=1, progress=False)
    assert not fake and res2.ran == 0 and res2.before == 8
    assert strip(rows_of(out / "results.parquet")) == strip(rows)
    table = summary_table(rows)
    assert "elevating" in table and "lowering" in table
    last = table.splitlines()[-1].split()
    assert last == ["all", "8", "4", "2", "2", "0", "0", "0", "0"]  # 4 recovered, 2 fell, 2 div.


def test_resumption_after_an_interruption(tmp_path, monkeypatch, capsys):
    out = tmp_path / "s"
    scs = small_grid(seed=[0, 1])  # 16 runs
    calls = []

    def interrupted_after_five(sc, **kw):
        if len(calls) == 5:
            raise KeyboardInterrupt
        calls.append(sc)
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", interrupted_after_five)
    with pytest.raises(StudyInterrupted, match="5 of 16 runs are stored"):
        run_study(scs, out, workers=1, progress=False)
    assert len(load_results(out)) == 5 and not (out / "results.parquet").exists()
    assert not list((out / "runs").glob("journal-*"))  # moved into a part on the way out

    again = []

    def counting(sc, **kw):
        again.append(sc)
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", counting)
    assert main(["study", "--out", str(out), "--swing", "0.2,0.4,0.6,0.85", "--speed",
                 "1.0,1.3", "--seed", "0,1", "--workers", "1", "--no-plots"]) == 0
    assert len(again) == 11  # only the missing runs
    assert {run_key(s) for s in again}.isdisjoint({run_key(s) for s in calls})
    assert len(rows_of(out / "results.parquet")) == 16
    assert "16 runs (11 run now, 5 before)" in capsys.readouterr().out


def test_interrupt_through_the_cli_exits_130(tmp_path, monkeypatch, capsys):
    def interrupt(sc, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "simulate_trip", interrupt)
    assert main(["study", "--out", str(tmp_path / "s"), "--workers", "1"]) == 130
    err = capsys.readouterr().err
    assert "interrupted: 0 of 1 runs are stored" in err and "run the same command" in err


def test_killed_study_loses_no_finished_run(tmp_path, fake):
    """SIGKILL in the middle: the journal keeps every finished run, the rerun does the rest."""
    out = tmp_path / "s"
    script = textwrap.dedent(f"""\
        import time
        from types import SimpleNamespace
        from stumble import pipeline
        from stumble.cli import main

        def slow(sc, **kw):
            time.sleep(0.15)
            return SimpleNamespace(summary={{"strategy": "elevating", "recovered": True,
                                             "fell": False, "diverged": False}})

        pipeline.simulate_trip = slow
        main(["study", "--out", {str(out)!r}, "--swing", "0.05:0.85:40", "--workers", "2",
              "--quiet", "--no-plots"])
        """)
    p = subprocess.Popen([sys.executable, "-c", script], stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    journal = []
    while time.monotonic() < deadline:
        journal = list((out / "runs").glob("journal-*.jsonl")) if out.exists() else []
        if journal and journal[0].read_text().count("\n") >= 6:
            break
        time.sleep(0.05)
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    stored = load_results(out)
    assert 6 <= len(stored) < 40
    assert not (out / "results.parquet").exists()
    res = run_study(Grid({"swing": parse_values("swing", "0.05:0.85:40")}).scenarios(), out,
                    workers=1, progress=False)
    assert len(fake) == 40 - len(stored) and len(res.rows) == 40
    assert not list((out / "runs").glob("journal-*"))  # the dead session's journal: a part


def test_failing_runs_are_rows_and_can_be_retried(tmp_path, fake, capsys):
    out = tmp_path / "s"
    args = ["study", "--out", str(out), "--controller", "fsm,reflex", "--swing", "0.2,0.6",
            "--workers", "1", "--no-plots"]
    assert main(args) == 0
    text = capsys.readouterr().out
    rows = rows_of(out / "results.parquet")
    reflex = [r for r in rows if r["controller"] == "reflex"]
    assert len(rows) == 4 and len(reflex) == 2
    assert all(r["error"] == "InputError: controller 'reflex' is not available (fsm)"
               for r in reflex)
    assert all(not r["recovered"] and r["strategy"] is None for r in reflex)
    assert all(r["error"] is None for r in rows if r["controller"] == "fsm")
    total = next(line for line in text.splitlines() if line.startswith("all"))
    assert "reflex -" in text and total.split()[-1] == "2"  # the errors column
    tb = (out / "errors" / f"{reflex[0]['key']}.txt").read_text()
    assert "Traceback" in tb and "not available" in tb
    fake.clear()
    assert main(args) == 0 and not fake  # errors are finished runs
    assert main([*args, "--retry-errors"]) == 0
    assert sorted(s.controller for s in fake) == ["reflex", "reflex"]


def test_local_processes_give_the_same_rows(tmp_path, fake):
    a = run_study(small_grid(), tmp_path / "a", workers=1, progress=False)
    b = run_study(small_grid(), tmp_path / "b", workers=2, progress=False)
    assert strip(a.rows) == strip(b.rows)


def test_a_worker_that_dies_is_one_error_row(tmp_path, monkeypatch):
    parent = os.getpid()

    def crash_at_0_6(sc, **kw):
        if sc.swing_fraction == 0.6 and os.getpid() != parent:
            os._exit(3)  # as a segfault would
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", crash_at_0_6)
    res = run_study(small_grid(), tmp_path / "s", workers=2, progress=False)
    dead = [r for r in res.rows if r["error"]]
    assert len(res.rows) == 8 and {r["swing_fraction"] for r in dead} == {0.6}
    assert all("WorkerDied" in r["error"] for r in dead)


def test_out_that_is_a_file_is_one_line(tmp_path, capsys, fake):
    (tmp_path / "f").write_text("")
    assert main(["study", "--out", str(tmp_path / "f"), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert "cannot make the study directory" in err and err.count("\n") == 1 and not fake


def test_one_study_per_directory(tmp_path):
    with Store(tmp_path / "s"), pytest.raises(StumbleError, match="in use by another"):
        Store(tmp_path / "s").__enter__()


def test_missing_pyarrow_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(StumbleError, match=r"needs pyarrow.*pip install pyarrow"):
        run_study(small_grid(), tmp_path / "s", workers=1, progress=False)


def test_plots_and_fall_rate(tmp_path, fake):
    out = tmp_path / "s"
    assert main(["study", "--out", str(out), "--swing", "0.2,0.4,0.6", "--speed", "1.0,1.3",
                 "--delay-scale", "1,1.5,2", "--workers", "1", "--quiet"]) == 0
    for name in ("strategy_map.png", "outcome_map.png", "fall_rate.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG", name
    assert main(["study", "--out", str(tmp_path / "t"), "--swing", "0.2,0.6", "--workers", "1",
                 "--quiet"]) == 0
    assert not (tmp_path / "t" / "fall_rate.png").exists()  # no scale varies


def test_maps_pool_only_within_a_panel():
    from stumble.viz.study_plots import Tally

    rows = [{"controller": c, "mechanism": "force", "swing_fraction": 0.2,
             "speed_m_per_s": 1.1} for c in ("fsm", "reflex")]
    assert not Tally.of(rows).pooled()  # two panels of one run each
    assert Tally.of(rows + rows[:1]).pooled()


def test_the_pooled_note_names_only_what_varies_within_a_panel():
    """A default that differs by controller (6 s after the trip for fsm, 3 s for the
    reflex controllers) is not a pooled axis; a value that varies within one panel is."""
    from stumble.viz.study_plots import Tally, _pooled_note

    rows = [{"controller": c, "mechanism": "obstacle", "swing_fraction": s,
             "speed_m_per_s": 1.2, "duration_after_trip_s": d, "seed": 0}
            for c, d in (("fsm", 6.0), ("reflex", 3.0)) for s in (0.2, 0.6)]
    assert _pooled_note(Tally.of(rows)) == ""
    seeds = [{**r, "seed": k} for r in rows for k in (1, 2, 3)]
    assert _pooled_note(Tally.of(seeds)) == "pooled over seed (3)"


def test_dask_cluster_gives_the_same_rows_as_local_processes(tmp_path, fake):
    """An in-process LocalCluster (threads, so the fake trips apply) against two local
    worker processes; the time limit works on its threads too."""
    distributed = pytest.importorskip("distributed")
    local = run_study(small_grid(), tmp_path / "a", workers=2, progress=False)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        res = run_study(small_grid(), tmp_path / "b", scheduler=cluster.scheduler_address,
                        progress=False)
    assert strip(res.rows) == strip(local.rows) and len(res.rows) == 8


def test_dask_cluster_runs_with_the_params(tmp_path, monkeypatch):
    """--params reach the Dask workers (threads here, so the fake applies): the rows of
    one local process, each from the file's trunk_attitude."""
    distributed = pytest.importorskip("distributed")
    from stumble.control.fsm_params import read_params

    def simulate_trip(sc, params=None):
        return SimpleNamespace(summary={**fake_summary(sc), "trunk_attitude":
                                        None if params is None else params.trunk_attitude})

    monkeypatch.setattr(pipeline, "simulate_trip", simulate_trip)
    pf = read_params(_params_file(tmp_path / "p.json"))
    local = run_study(small_grid(), tmp_path / "a", workers=1, progress=False, params=pf)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        res = run_study(small_grid(), tmp_path / "b", scheduler=cluster.scheduler_address,
                        progress=False, params=pf)
    assert strip(res.rows) == strip(local.rows) and len(res.rows) == 8
    assert all(r["trunk_attitude"] == 1.0 for r in res.rows)


def test_dask_time_limit_on_worker_threads(tmp_path, monkeypatch):
    distributed = pytest.importorskip("distributed")

    def slow_at_0_6(sc, **kw):
        if sc.swing_fraction == 0.6:
            while True:
                pass
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", slow_at_0_6)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        res = run_study(small_grid(), tmp_path / "s", scheduler=cluster.scheduler_address,
                        progress=False, run_timeout_s=0.5)
    assert {r["swing_fraction"] for r in res.rows if r["timed_out"]} == {0.6}


def test_real_trips_on_a_process_cluster_match_local_processes(tmp_path):
    """Real trips on a LocalCluster of worker processes (as on a cluster: a fresh
    interpreter that imports stumble) give the rows of two local processes."""
    distributed = pytest.importorskip("distributed")
    scs = Grid({"swing": [0.2, 0.65], "duration": [0.6]}).scenarios()
    local = run_study(scs, tmp_path / "a", workers=2, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        res = run_study(scs, tmp_path / "b", scheduler=cluster.scheduler_address,
                        progress=False)
    assert strip(res.rows) == strip(local.rows)
    assert [r["strategy"] for r in res.rows] == ["elevating", "lowering"]
    assert all(r["error"] is None for r in res.rows)


def test_unreachable_scheduler_is_one_line(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(runner, "CONNECT_TIMEOUT_S", 1.0)
    assert main(["study", "--out", str(tmp_path / "s"), "--scheduler",
                 "tcp://127.0.0.1:1"]) == 2
    err = capsys.readouterr().err
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:1" in err
    assert err.count("\n") == 1 and not (tmp_path / "s").exists()
    # a malformed address: one line at once (it once left a half-made client that
    # stalled the exit 40 s and printed a traceback)
    for bad in ("nope", "", "tcp://", "http://x:1"):
        tic = time.perf_counter()
        assert main(["study", "--out", str(tmp_path / "s"), "--scheduler", bad]) == 2
        err = capsys.readouterr().err
        assert f"--scheduler {bad!r} is not a Dask scheduler address" in err
        assert err.count("\n") == 1 and time.perf_counter() - tic < 5.0
    for good in ("[::1]:8786", "scheduler-0.cluster.local:8786", "tls://h:1",
                 "inproc://192.0.2.2/22314/1"):
        runner.check_scheduler_address(good)


# ---------------------------------------------------------------- real trips


def test_real_trips_through_the_cli(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["study", "--out", str(out), "--swing", "0.2,0.65", "--speed", "1.2",
                 "--duration", "0.6", "--workers", "2", "--quiet"]) == 0
    rows = rows_of(out / "results.parquet")
    assert [r["strategy"] for r in rows] == ["elevating", "lowering"]
    assert all(r["error"] is None and 0 < r["steps"] <= 600 for r in rows)
    assert all(r["trip_time_s"] > 0.4 and r["wall_time_s"] > 0 for r in rows)
    # deterministic: the same numbers as a trip run here and now
    direct = flatten(pipeline.simulate_trip(Scenario(
        swing_fraction=0.2, speed_m_per_s=1.2, duration_after_trip_s=0.6)).summary)
    for k, v in direct.items():
        if k not in WALL:
            assert rows[0][k] == v, k
    assert (out / "strategy_map.png").exists() and (out / "outcome_map.png").exists()


def _params_file(path: Path) -> Path:
    """A parameter file that matters: SCA's 60 deg push-off plantarflexion (elevating) and
    the trunk held against 1.0 times its forward pitch."""
    path.write_text(json.dumps({"params": {"elev_sup_ankle": -60.0},
                                "settings": {"trunk_attitude": 1.0}}))
    return path


def test_real_trips_with_params_differ_and_match_on_one_or_two_workers(tmp_path, capsys):
    from stumble.control.fsm_params import load_params

    p = _params_file(tmp_path / "p.json")
    grid = ["--swing", "0.2,0.65", "--speed", "1.2", "--duration", "0.6", "--quiet",
            "--no-plots"]
    for name, extra in (("two", ["--workers", "2", "--params", str(p)]),
                        ("one", ["--workers", "1", "--params", str(p)]),
                        ("default", ["--workers", "1", "--params", "step"])):
        assert main(["study", "--out", str(tmp_path / name), *grid, *extra]) == 0
    two, one, default = (rows_of(tmp_path / n / "results.parquet")
                         for n in ("two", "one", "default"))
    assert strip(two) == strip(one)  # the parameters reach the worker processes
    assert [r["key"] for r in two] == [r["key"] for r in default]  # run keys: the scenario's
    # the trunk held upright: far less tilt at recovery-foot contact than the step set's
    tilt = [(r["trunk_tilt_at_recovery_contact_deg"],
             d["trunk_tilt_at_recovery_contact_deg"]) for r, d in zip(two, default, strict=True)]
    assert tilt[0][0] < tilt[0][1] - 5.0, tilt  # elevating at 0.2 of swing: ~14 against ~24
    assert two[0]["support_peak_moments_nm.ankle_plantarflexion"] > \
        default[0]["support_peak_moments_nm.ankle_plantarflexion"]
    # each row is the trip run here with those parameters
    direct = flatten(pipeline.simulate_trip(Scenario(
        swing_fraction=0.2, speed_m_per_s=1.2, duration_after_trip_s=0.6),
        params=load_params(p)).summary)
    for k, v in direct.items():
        if k not in WALL:
            assert two[0][k] == v, k


def test_params_go_to_every_run_and_are_recorded(tmp_path, monkeypatch, capsys):
    import hashlib

    from stumble.control.fsm_params import TUNABLE

    got = []

    def simulate_trip(sc, **kw):
        got.append(kw.get("params"))
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", simulate_trip)
    p = _params_file(tmp_path / "p.json")
    argv = ["study", "--swing", "0.2,0.4", "--workers", "1", "--quiet", "--no-plots"]
    assert main([*argv, "--out", str(tmp_path / "a"), "--params", str(p)]) == 0
    assert len(got) == 2 and all(g.trunk_attitude == 1.0 for g in got)
    assert all(g.targets_deg["clearance_elevating"]["sup.ankle_angle"] == -60.0 for g in got)
    rec = json.loads((tmp_path / "a" / "study.json").read_text())["params"]
    assert rec["path"] == str(p) and rec["file"] == str(p.resolve())
    assert rec["sha256"] == hashlib.sha256(p.read_bytes()).hexdigest()
    # the values of SPACE, GAINS and WALK_ON
    assert rec["values"]["elev_sup_ankle"] == -60.0 and len(rec["values"]) == len(TUNABLE) == 65
    assert rec["settings"] == {"trunk_attitude": 1.0, "attitude_damping": "joint",
                               "push_off_hip_limit_nm": None,
                               "push_off_rec_hip_limit_nm": None,
                               "push_off_sup_knee_limit_nm": None,
                               "flight_from_fall": False}
    table = pq.read_table(tmp_path / "a" / "results.parquet").to_pydict()
    assert table["params_sha256"] == [rec["sha256"]] * 2  # every row names its parameters
    # without --params: no parameters passed, nothing recorded as given (as before
    # --params existed), and the sets the trips run by default named
    got.clear()
    assert main([*argv, "--out", str(tmp_path / "b")]) == 0
    assert got == [None, None]
    meta = json.loads((tmp_path / "b" / "study.json").read_text())
    assert "params" not in meta
    from stumble.control.fsm_params import read_params

    assert {k: v["name"] for k, v in meta["fsm_default_params"].items()} == {
        "fixed walk_on": "rec_hip_cap", "fixed step": "rec_hip_cap",
        "anderson2007 walk_on": "anderson2007_walk_on", "anderson2007 step": "anderson2007"}
    assert meta["fsm_default_params"]["fixed walk_on"]["sha256"] == read_params(
        "rec_hip_cap").sha256
    assert "params_sha256" not in pq.read_table(tmp_path / "b" / "results.parquet").schema.names
    # a shipped set by name
    assert main([*argv, "--out", str(tmp_path / "c"), "--params", "anderson2007"]) == 0
    assert json.loads((tmp_path / "c" / "study.json").read_text())["params"]["path"] == \
        "anderson2007"
    capsys.readouterr()
    # a directory holds one parameter set: resuming with others is one line, nothing run
    got.clear()
    for out, extra, words in (("a", [], "made with --params of SHA-256 " + rec["sha256"][:16]),
                              ("b", ["--params", str(p)], "made without --params"),
                              ("a", ["--params", "anderson2007"], "resumed with --params "
                               "anderson2007")):
        assert main([*argv, "--out", str(tmp_path / out), *extra]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err
    assert not got
    # the same bytes under another name resume it: nothing to run
    same = tmp_path / "same.json"
    same.write_bytes(p.read_bytes())
    assert main([*argv, "--out", str(tmp_path / "a"), "--params", str(same)]) == 0
    assert not got and "2 runs (0 run now, 2 before)" in capsys.readouterr().out
    # runs made without --params by a version with other default sets (or none recorded,
    # as before 2026-12-03) are not resumed: the defaults' runs must not mix either
    assert main([*argv, "--out", str(tmp_path / "b")]) == 0  # the same defaults: resumed
    assert not got
    capsys.readouterr()
    study = tmp_path / "b" / "study.json"
    for change in ({"fsm_default_params": {"fixed walk_on": {"name": "upright",
                                                             "sha256": "0" * 64}}},
                   {"fsm_default_params": None}):
        study.write_text(json.dumps({**json.loads(study.read_text()), **change}))
        assert main([*argv, "--out", str(tmp_path / "b")]) == 2
        err = capsys.readouterr().err
        assert "other default state-machine parameters" in err and err.count("\n") == 1
    assert not got


def test_a_study_file_names_its_params_relative_to_itself(tmp_path, monkeypatch, capsys):
    """``params = "p.json"`` in a TOML study file is the file beside it (whatever the
    working directory); ``--params`` on the command line wins; the maps' caption names
    it; a value that is not a string is one line."""
    from stumble.study.cli import params_caption

    got = []

    def simulate_trip(sc, **kw):
        got.append(kw.get("params"))
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", simulate_trip)
    d = tmp_path / "studies"
    d.mkdir()
    p = _params_file(d / "p.json")
    toml = d / "s.toml"
    toml.write_text('params = "p.json"\nswing = [0.2, 0.4]\n')
    argv = ["study", str(toml), "--workers", "1", "--quiet", "--no-plots"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    assert len(got) == 2 and all(g.trunk_attitude == 1.0 for g in got)
    rec = json.loads((tmp_path / "a" / "study.json").read_text())["params"]
    assert rec["path"] == str(p)
    assert params_caption(tmp_path / "a") == (f"state-machine parameters: {p} "
                                              f"(SHA-256 {rec['sha256'][:12]})")
    assert params_caption(tmp_path / "nowhere") == ""
    got.clear()
    assert main([*argv, "--out", str(tmp_path / "b"), "--params", "anderson2007"]) == 0
    assert json.loads((tmp_path / "b" / "study.json").read_text())["params"]["path"] == \
        "anderson2007"
    assert load_toml(toml).params == str(p)
    toml.write_text("params = 3\n")
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "s.toml: params must be a file name" in err and err.count("\n") == 1


@pytest.mark.parametrize(("extra", "words"), [
    (["--controller", "reflex"], "--params is for --controller fsm in a study (the grid has "
     "reflex)"),
    (["--controller", "fsm,gh2010"], "(the grid has gh2010)"),
])
def test_params_for_other_controllers_is_one_line(tmp_path, capsys, fake, extra, words):
    code = main(["study", "--out", str(tmp_path / "s"), "--params", "anderson2007", *extra])
    err = capsys.readouterr().err
    assert code == 2 and words in err and err.count("\n") == 1 and not fake
    assert not (tmp_path / "s").exists()


# ---------------------------------------------------------------- hardening


def test_a_grid_too_big_is_refused_from_its_count(tmp_path, capsys, fake):
    t0 = time.monotonic()
    code = main(["study", "--out", str(tmp_path / "s"), "--swing", "0.05:0.9:1000",
                 "--speed", "0.7:1.6:1000", "--repeats", "1000"])
    assert code == 2 and time.monotonic() - t0 < 5.0
    err = capsys.readouterr().err
    assert "the grid has 1,000,000,000 runs, more than the limit of 10,000,000" in err
    assert err.count("\n") == 1 and not (tmp_path / "s").exists() and not fake
    g = Grid({"swing": parse_values("swing", "0.1:0.7:4"), "mechanism": ["force", "obstacle"],
              "obstacle_height": [0.08, 0.14]})
    assert g.count() == len(list(g.iter_scenarios())) == 4 * (1 + 2)


@pytest.mark.parametrize("args, words", [
    (["--seed", str(2**63)], f"seed {2**63} is not a whole number from 0 to {2**63 - 1}"),
    (["--seed", "-1"], "seed -1 is not a whole number from 0"),
    (["--controller", "reflex", "--mechanism", "obstacle", "--timestep", "0.0003"],
     "the time step (0.3 ms) must divide it"),
    (["--out", ""], "the output directory is empty"),
    # force trips ignore the height, but a height out of range is still an error
    (["--obstacle-height", "0"], "obstacle height 0.0 m is outside 0.02-0.3 m"),
    (["--mechanism", "force", "--obstacle-height", "0.1,0.5"],
     "obstacle height 0.5 m is outside 0.02-0.3 m"),
    # likewise a walk-in with a playback start, delays for the state machines
    (["--walk-in", "1"], "walk-in 1.0 s is outside 2-30 s"),
    (["--controller", "fsm", "--delays", "bogus"], "delays 'bogus' is not one of"),
])
def test_every_scenario_is_checked_before_anything_runs(tmp_path, capsys, fake, args, words):
    out = tmp_path / "s"
    argv = ["study", "--out", str(out), *args]
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err
    assert code == 2 and words in err and err.count("\n") == 1, err
    assert not out.exists() and not fake


def test_an_unwritable_study_directory_is_one_line(tmp_path, capsys, fake):
    if os.geteuid() == 0:  # root writes through mode bits: /proc refuses anyone
        out = Path("/proc")
    else:
        out = tmp_path / "ro"
        out.mkdir()
        out.chmod(0o555)
    assert main(["study", "--out", str(out), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert str(out) in err and err.count("\n") == 1 and not fake


def _journal_line(row: dict) -> str:
    return json.dumps(row)


def test_bad_journal_rows_are_skipped_with_a_warning_and_run_again(tmp_path, fake, capsys):
    """A crashed session's journal with a non-UTF-8 line, an edited row, a row of wrong
    types, a row without a checksum and a seed beyond 64 bits: each skipped with one line
    naming the file and line; the good row is kept; the rest are run again."""
    from stumble.study.store import with_checksum

    out = tmp_path / "s"
    scs = small_grid()
    run_study(scs[:1], out, workers=1, progress=False)
    good = rows_of(out / "results.parquet")[0]
    (out / "results.parquet").unlink()
    for part in (out / "runs").glob("part-*"):
        part.unlink()
    rows = [with_checksum(runner.make_row(sc, fake_summary(sc), None, 0.1)) for sc in scs[1:5]]
    edited = dict(rows[1], recovered=not rows[1]["recovered"])  # checksum no longer matches
    typed = with_checksum(dict(rows[2], recovered="yes"))
    poisoned = with_checksum(dict(rows[3], seed=2**64))
    no_sum = {k: v for k, v in rows[0].items() if k != "checksum"}
    journal = out / "runs" / "journal-dead.jsonl"
    lines = [_journal_line(good).encode(), b"\xff\xfe not utf-8", _journal_line(edited).encode(),
             _journal_line(typed).encode(), _journal_line(poisoned).encode(),
             _journal_line(no_sum).encode(), b'{"key": "half-writ']
    journal.write_bytes(b"\n".join(lines))
    fake.clear()
    capsys.readouterr()
    res = run_study(scs, out, workers=1, progress=False)
    err = capsys.readouterr().err.splitlines()
    warnings = [w for w in err if w.startswith("stumble: warning:")]
    assert len(warnings) == 5, err  # the half-written last line is a killed session's
    for n, words in [(2, "not UTF-8 text"), (3, "its checksum does not match"),
                     (4, "recovered = 'yes' is text"), (5, f"seed = {2**64} does not fit"),
                     (6, "it has no checksum")]:
        assert any(f"journal-dead.jsonl line {n}" in w and words in w for w in warnings), words
    assert any(f"(key {rows[1]['key']})" in w for w in warnings)  # the row is named
    assert res.before == 1 and len(fake) == len(scs) - 1 and res.runs == len(scs)
    assert (out / "runs" / "corrupt-journal-dead.jsonl").exists()  # kept to look at
    # the directory is not stuck: the next session has nothing to do and no warning
    fake.clear()
    res = run_study(scs, out, workers=1, progress=False)
    assert res.ran == 0 and "warning" not in capsys.readouterr().err


def test_results_come_in_grid_order_from_many_parts_and_chunks(tmp_path, monkeypatch, fake):
    """Rows written in parts of 3, assembled 2 at a time; an error row retried later wins
    over nothing but loses to a row without error, whatever the part order."""
    from stumble.study import store

    monkeypatch.setattr(store, "PART_ROWS", 3)
    monkeypatch.setattr(store, "RESULT_CHUNK_ROWS", 2)
    scs = small_grid(seed=[0, 1])
    a = run_study(scs, tmp_path / "a", workers=2, progress=False)
    assert [r["key"] for r in a.rows] == [run_key(s) for s in scs]
    assert len(list((tmp_path / "a" / "runs").glob("part-*"))) >= 6
    b = run_study(scs, tmp_path / "b", workers=1, progress=False)
    assert strip(a.rows) == strip(b.rows)


def test_a_run_past_its_time_limit_is_a_timeout_row(tmp_path, monkeypatch, capsys):
    def slow_at_0_6(sc, **kw):
        if sc.swing_fraction == 0.6:
            while True:  # stuck in Python
                pass
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", slow_at_0_6)
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        t0 = time.monotonic()
        res = run_study(small_grid(), out, workers=workers, progress=False, run_timeout_s=0.5)
        assert time.monotonic() - t0 < 15
        late = [r for r in res.rows if r["timed_out"]]
        assert {r["swing_fraction"] for r in late} == {0.6} and len(late) == 2
        assert all("RunTimeout: the run took more than 0.5 s" in r["error"] for r in late)
        assert all(0.5 <= r["run_wall_time_s"] < 5 for r in late)
        assert summary_table(res.rows).splitlines()[-1].split()[-2] == "2"  # timeout column


def test_a_run_stuck_in_c_is_killed_with_its_worker(tmp_path, monkeypatch):
    def stuck_at_0_6(sc, **kw):
        if sc.swing_fraction == 0.6:
            time.sleep(60)  # a C call: no Python instruction to stop at
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", stuck_at_0_6)
    monkeypatch.setattr(runner, "HARD_KILL_GRACE_S", 0.5)
    t0 = time.monotonic()
    res = run_study(small_grid(), tmp_path / "s", workers=2, progress=False, run_timeout_s=0.5)
    assert time.monotonic() - t0 < 30
    late = {r["swing_fraction"] for r in res.rows if r["timed_out"]}
    assert late == {0.6} and sum(r["error"] is None for r in res.rows) == 6


def test_run_timeout_option(tmp_path, capsys, monkeypatch):
    def forever(sc, **kw):
        while True:
            pass

    monkeypatch.setattr(pipeline, "simulate_trip", forever)
    assert main(["study", "--out", str(tmp_path / "s"), "--workers", "1", "--run-timeout",
                 "0.3", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "timeout" in text.splitlines()[0] and text.splitlines()[-2].split()[-2] == "1"
    assert (tmp_path / "s" / "outcome_map.png").exists()
    for bad, words in (("-1", "must be a number of seconds >= 0"),
                       ("1e300", "more than a week")):  # 1e300: past the platform's clock
        with pytest.raises(SystemExit):
            main(["study", "--out", str(tmp_path / "t"), "--run-timeout", bad])
        assert words in capsys.readouterr().err


def test_a_summary_with_nan_is_stored_as_null(tmp_path, monkeypatch):
    def nan_tilt(sc, **kw):
        return SimpleNamespace(summary={**fake_summary(sc), "trunk_tilt_at_recovery_contact_deg":
                                        float("nan"), "states": [{"start_s": float("inf")}]})

    monkeypatch.setattr(pipeline, "simulate_trip", nan_tilt)
    res = run_study(small_grid()[:2], tmp_path / "s", workers=1, progress=False)
    assert [r["trunk_tilt_at_recovery_contact_deg"] for r in res.rows] == [None, None]
    assert json.loads(res.rows[0]["states"]) == [{"start_s": None}]


def test_a_trip_that_cannot_be_set_is_an_outcome_not_an_error(tmp_path, monkeypatch):
    """A reflex walker's toe over the obstacle at the trip's instant (``TripNotSet``): the
    run's row says ``not_set`` with the reason and no error or traceback; the table counts
    it apart, the maps mark it ×, and no fall rate counts it."""
    from stumble.errors import TripNotSet
    from stumble.study.runner import outcome
    from stumble.viz.study_plots import Tally

    def simulate_trip(sc, **kw):
        if sc.swing_fraction == 0.6:
            raise TripNotSet("at 0.6 of swing the gh2010 walker's toe is 0.12 m up, not "
                             "0.01 m below a 0.1 m obstacle's top: it would clear it")
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", simulate_trip)
    out = tmp_path / "s"
    assert main(["study", "--out", str(out), "--swing", "0.2,0.6", "--speed", "1.0,1.3",
                 "--delay-scale", "1,2", "--workers", "1", "--quiet"]) == 0
    rows = rows_of(out / "results.parquet")
    not_set = [r for r in rows if r["swing_fraction"] == 0.6]
    assert len(not_set) == 4 and all(r["not_set"] and r["error"] is None for r in not_set)
    assert all("toe is 0.12 m up" in r["not_set_reason"] for r in not_set)
    assert {outcome(r) for r in not_set} == {"not set"}
    assert not (out / "errors").exists() or not any((out / "errors").iterdir())
    last = summary_table(rows).splitlines()[-1].split()
    assert last == ["all", "8", "4", "0", "0", "0", "4", "0", "0"]
    t = Tally.of(rows)  # the fall rate counts only the trips that were set
    assert all(runs == 2 for by_x in t.fall.values() for _f, runs in by_x.values())
    assert (out / "fall_rate.png").exists() and (out / "strategy_map.png").exists()


def test_a_reflex_study_is_not_resumed_with_other_default_reflex_sets(tmp_path, capsys,
                                                                        monkeypatch):
    """``study.json`` records the network and GH2010 set the reflex controllers run by
    default (name and SHA-256: they changed on 2026-12-04); a directory whose runs were
    made with others, or before they were recorded, is not resumed."""
    import hashlib
    from importlib import resources

    got = []

    def simulate_trip(sc, **kw):
        got.append(sc)
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", simulate_trip)
    out = tmp_path / "g"
    argv = ["study", "--controller", "gh2010", "--swing", "0.2,0.6", "--workers", "1",
            "--quiet", "--out", str(out)]
    assert main(argv) == 0 and len(got) == 2
    meta = json.loads((out / "study.json").read_text())["reflex_default_params"]
    data = resources.files("stumble.control.reflex") / "data"
    name = "gh2010_knee_2ms_dense_wide_s3.json"  # the default since 2026-12-05
    assert meta == {"gh2010": {"name": name, "sha256": hashlib.sha256(
        (data / name).read_bytes()).hexdigest()}}
    assert {sc.timestep_s for sc in got} == {0.002}  # run at the default set's step
    assert main(argv) == 0 and len(got) == 2  # the same defaults: resumed, nothing run
    capsys.readouterr()
    study = out / "study.json"
    for change in ({"reflex_default_params": {"gh2010": {"name": "gh2010.json",
                                                         "sha256": "0" * 64}}},
                   {"reflex_default_params": None}):
        study.write_text(json.dumps({**json.loads(study.read_text()), **change}))
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "other default reflex parameters" in err and err.count("\n") == 1
    assert len(got) == 2


def test_a_directory_grows_by_a_controller_and_keeps_each_ones_defaults(tmp_path, capsys,
                                                                        monkeypatch):
    """Runs of one controller do not stop a grid of another from using the directory
    (it once refused, blaming an earlier version's defaults): study.json keeps the
    default sets of every controller with runs there, and a changed set still refuses
    the directory for that controller's grid, naming it."""
    got = []

    def simulate_trip(sc, **kw):
        got.append(sc.controller)
        return SimpleNamespace(summary=fake_summary(sc))

    monkeypatch.setattr(pipeline, "simulate_trip", simulate_trip)
    out = tmp_path / "mix"
    argv = ["study", "--swing", "0.2", "--workers", "1", "--quiet", "--no-plots",
            "--out", str(out), "--controller"]
    assert main([*argv, "gh2010"]) == 0
    assert main([*argv, "fsm"]) == 0  # refused before 2026-12-07
    assert main([*argv, "gh2010"]) == 0 and got == ["gh2010", "fsm"]  # nothing re-run
    meta = json.loads((out / "study.json").read_text())
    assert set(meta["reflex_default_params"]) == {"gh2010"}
    assert meta["fsm_default_params"]  # kept by a gh2010 grid: the fsm runs are there
    assert main([*argv, "fsm,gh2010,reflex"]) == 0 and got[2:] == ["reflex"]
    capsys.readouterr()
    meta = json.loads((out / "study.json").read_text())
    meta["reflex_default_params"]["reflex"]["sha256"] = "0" * 64
    (out / "study.json").write_text(json.dumps(meta))
    assert main([*argv, "gh2010"]) == 0  # the network's record is not gh2010's
    capsys.readouterr()
    assert main([*argv, "reflex"]) == 2
    err = capsys.readouterr().err
    assert "holds reflex runs made with other default reflex parameters" in err
    assert err.count("\n") == 1 and len(got) == 3


@pytest.mark.parametrize("name", ["results.parquet", "study.json"])
def test_a_directory_where_a_result_file_goes_is_refused_before_any_run(
        tmp_path, capsys, monkeypatch, name):
    """DIR/results.parquet or DIR/study.json as a directory: one line before the first
    run (it once failed with a traceback after every run was done)."""
    ran = []
    monkeypatch.setattr(pipeline, "simulate_trip",
                        lambda sc, **kw: ran.append(sc) or SimpleNamespace(
                            summary=fake_summary(sc)))
    (tmp_path / "s" / name).mkdir(parents=True)
    assert main(["study", "--out", str(tmp_path / "s"), "--workers", "1", "--quiet",
                 "--swing", "0.2"]) == 2
    err = capsys.readouterr().err
    assert f"{name} is a directory: the study writes that file" in err
    assert err.count("\n") == 1 and ran == []


@pytest.mark.parametrize("text, says", [("{bad", "cannot be read"),
                                        ("[]", "is not a study record")])
def test_a_corrupt_study_record_is_named_as_such(tmp_path, capsys, monkeypatch, text, says):
    """A study directory with runs whose study.json is corrupt: one line saying so (it once
    blamed an earlier version's default parameters)."""
    monkeypatch.setattr(pipeline, "simulate_trip",
                        lambda sc, **kw: SimpleNamespace(summary=fake_summary(sc)))
    argv = ["study", "--out", str(tmp_path / "s"), "--workers", "1", "--quiet", "--no-plots",
            "--swing", "0.2"]
    assert main(argv) == 0
    (tmp_path / "s" / "study.json").write_text(text)
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"study.json {says}" in err and err.count("\n") == 1
