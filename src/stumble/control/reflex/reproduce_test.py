"""The recorded chains of fits of the shipped sets, read back and re-run as one job."""

from __future__ import annotations

import itertools
import json
import shutil
from importlib import resources
from pathlib import Path

import pytest

from stumble.cli import main
from stumble.control.reflex.gh2010 import NAMED
from stumble.control.reflex.identify import NETWORK_NAMES
from stumble.control.reflex.reproduce import plan, run
from stumble.errors import InputError

DATA = resources.files("stumble.control.reflex") / "data"


def _arg(argv: list[str], opt: str) -> str | None:
    return argv[argv.index(opt) + 1] if opt in argv else None


def test_the_gh2010_default_is_five_fits_from_the_papers_gains(tmp_path):
    kind, stages = plan("knee-2ms-dense-wide-s3", tmp_path)
    assert kind == "gh2010"
    assert [s.tag for s in stages] == ["pushed-walk", "knee-walk", "knee-2ms",
                                       "knee-2ms-dense", "knee-2ms-dense-wide-s3"]
    assert _arg(stages[0].argv, "--params") is None  # the paper's gains
    for before, st in itertools.pairwise(stages):
        assert _arg(st.argv, "--params") == str(tmp_path / before.tag / "gh2010.json")
    for st in stages:
        assert _arg(st.argv, "--out") == str(tmp_path / st.tag)
        assert st.argv[:2] == ["reflex", "fit"]
    assert _arg(stages[-1].argv, "--seed") == "3"
    assert 25 < sum(s.minutes for s in stages) < 40  # docs/reflex.md: 32 min


def test_the_default_network_runs_from_the_papers_gains_both_branches_shared_once(tmp_path):
    """Its expert's five fits from the paper's gains, DAgger (``placement``, a root whose
    command is known, ``reproduce.ROOTS``), then the eight CMA-ES fits."""
    kind, stages = plan("placement-both", tmp_path)
    tags = [s.tag for s in stages]
    assert kind == "network"
    assert tags == ["pushed-walk", "knee-walk", "e2", "e3", "expert-placement", "placement",
                    "es1", "placement-es", "placement-walk", "tr3", "placement-touch",
                    "tr4", "placement-foot", "placement-both"]
    dagger = stages[5].argv
    assert "--closed-loop" in dagger and _arg(dagger, "--seed") == "0"
    assert _arg(dagger, "--expert") == str(tmp_path / "expert-placement" / "gh2010.json")
    assert _arg(stages[6].argv, "--walk-es") == str(tmp_path / "placement" / "network.npz")
    last = stages[-1].argv
    assert _arg(last, "--walk-es") == str(tmp_path / "placement-touch" / "network.npz")
    assert _arg(last, "--ahead-from") == str(tmp_path / "placement-foot" / "network.npz")
    assert _arg(stages[11].argv, "--walk-es") == str(tmp_path / "placement-walk" /
                                                     "network.npz")


@pytest.mark.parametrize(("name", "root", "mid", "seed"), [
    ("cross-entropy-foot", "cross-entropy", "cef", "0"),
    ("cross-entropy-s1-foot", "cross-entropy-s1", "ces1f", "1")])
def test_the_cross_entropy_branches_are_dagger_by_its_loss_then_two_touch_stages(
        tmp_path, name, root, mid, seed):
    """``cross-entropy-foot`` and ``cross-entropy-s1-foot``: the expert's five fits,
    DAgger by the cross-entropy through pushes (by seed 0 and 1, each a root of its own,
    ``reproduce.ROOTS``), then the same two touch stages by the foot's place, on the
    dense then the wide trips. ``cross-entropy-foot``'s: 44.8 min recorded after the
    expert (the first touch stage with another fit on the machine; 31 min idle)."""
    kind, stages = plan(name, tmp_path)
    tags = [s.tag for s in stages]
    assert kind == "network"
    assert tags == ["pushed-walk", "knee-walk", "e2", "e3", "expert-placement", root, mid,
                    name]
    dagger = stages[5].argv
    assert "--closed-loop" in dagger and "--pushes" in dagger
    assert _arg(dagger, "--loss") == "cross-entropy" and _arg(dagger, "--seed") == seed
    assert _arg(dagger, "--expert") == str(tmp_path / "expert-placement" / "gh2010.json")
    assert _arg(stages[6].argv, "--walk-es") == str(tmp_path / root / "network.npz")
    assert _arg(stages[7].argv, "--walk-es") == str(tmp_path / mid / "network.npz")
    assert all(_arg(s.argv, "--scr-phase") == "foot" for s in stages[6:])
    assert [_arg(s.argv, "--trip-set") for s in stages[6:]] == ["dense", "wide"]
    if name == "cross-entropy-foot":
        assert 40 < sum(s.minutes for s in stages[5:]) < 50


def _copying_runner(calls: list, change=None):
    """Stands in for ``stumble``: writes the shipped file of the stage's name (the last
    part of its ``--out``), as a fit that reproduces it would; ``change(path)`` edits it."""
    def runner(argv: list[str]) -> int:
        calls.append(argv)
        out = Path(_arg(argv, "--out"))
        out.mkdir(parents=True, exist_ok=True)
        name = out.name
        if "--closed-loop" in argv or _arg(argv, "--controller") == "network":
            src = DATA / NETWORK_NAMES[name] if name in NETWORK_NAMES else DATA / NETWORK_NAMES[
                "placement-walk"]
            dst = out / "network.npz"
        else:  # (an unshipped expert stage: any seed003-wired set)
            src = DATA / NAMED.get(name, NAMED["expert-placement"])
            dst = out / "gh2010.json"
        shutil.copyfile(src, dst)
        if change is not None:
            change(dst)
        return 0
    return runner


def test_a_run_compares_each_shipped_result_and_resumes(tmp_path):
    calls: list = []
    rep = run("knee-2ms-dense-wide-s3", tmp_path, runner=_copying_runner(calls))
    assert len(calls) == 5
    assert [s["same_as_shipped"] for s in rep["stages"]] == [True] * 5
    assert rep["same_as_shipped"] is True
    saved = json.loads((tmp_path / "reproduce.json").read_text())
    assert saved["stages"][-1]["tag"] == "knee-2ms-dense-wide-s3"
    assert saved["result"] == str(tmp_path / "knee-2ms-dense-wide-s3" / "gh2010.json")
    # run again: every result is there, nothing is re-run
    again: list = []
    rep2 = run("knee-2ms-dense-wide-s3", tmp_path, runner=_copying_runner(again))
    assert again == []
    assert all("kept" in s["note"] for s in rep2["stages"])


def test_the_default_network_from_the_papers_gains_checks_each_kind_of_result(tmp_path):
    """The expert's stages write Geyer & Herr sets, DAgger and the rest networks: each
    result is looked for, and compared, as what its stage fits."""
    calls: list = []
    rep = run("placement-both", tmp_path, runner=_copying_runner(calls))
    assert len(calls) == 14
    by_tag = {s["tag"]: s for s in rep["stages"]}
    assert (tmp_path / "expert-placement" / "gh2010.json").exists()
    assert (tmp_path / "placement" / "network.npz").exists()
    for tag in ("pushed-walk", "knee-walk", "expert-placement", "placement", "placement-es",
                "placement-walk", "placement-touch", "placement-foot", "placement-both"):
        assert by_tag[tag]["same_as_shipped"] is True, tag
    assert "same_as_shipped" not in by_tag["e2"]  # not shipped: not compared
    assert rep["same_as_shipped"] is True


def test_a_result_that_differs_names_the_parameter(tmp_path):
    def nudge(path: Path) -> None:
        d = json.loads(path.read_text())
        d["params"]["g_scr_ta"] = d["params"]["g_scr_ta"] + 1e-12
        path.write_text(json.dumps(d))

    rep = run("knee-2ms-dense-wide-s3", tmp_path, start_after="knee-2ms-dense",
              runner=_copying_runner([], change=nudge))
    (only,) = rep["stages"]
    assert only["same_as_shipped"] is False
    assert only["difference"].startswith("g_scr_ta")


def test_from_a_shipped_result_starts_there(tmp_path):
    calls: list = []
    rep = run("placement-both", tmp_path, start_after="placement-touch",
              runner=_copying_runner(calls))
    assert [Path(_arg(a, "--out")).name for a in calls] == ["tr4", "placement-foot",
                                                            "placement-both"]
    assert _arg(calls[0], "--walk-es") == "placement-walk"  # the shipped file
    assert _arg(calls[-1], "--walk-es") == "placement-touch"
    assert rep["stages"][-1]["same_as_shipped"] is True


def test_a_failing_stage_stops_the_job_and_says_which(tmp_path):
    with pytest.raises(InputError, match=r"stage 1 \(pushed-walk\) failed \(exit status 2\)"):
        run("knee-2ms-dense-wide-s3", tmp_path, runner=lambda argv: 2)
    saved = json.loads((tmp_path / "reproduce.json").read_text())
    assert saved["stages"][0]["error"] == "exit status 2"


@pytest.mark.parametrize("args, says", [
    (["nothing"], "'nothing' is not a shipped parameter set or network"),
    (["closed-loop"], "'closed-loop' records no fit command"),
    (["open-loop"], "'open-loop' records no fit command"),
    (["placement-both", "--from", "knee-2ms"], "--from 'knee-2ms': not a shipped result"),
])
def test_bad_names_get_one_line(tmp_path, capsys, args, says):
    assert main(["reflex", "reproduce", *args, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and says in err
    assert not (tmp_path / "o").exists()  # refused before the directory is made


@pytest.mark.parametrize("plan_only", [False, True])
def test_an_out_that_cannot_be_a_directory_gets_one_line(tmp_path, capsys, plan_only):
    """An existing file, or a path under one, as --out: one line, exit 2, no stage run."""
    f = tmp_path / "afile"
    f.write_text("")
    for out, says in ((f, "exists and is not a directory"),
                      (f / "sub", "cannot create output directory")):
        if plan_only and out != f:
            continue  # --plan makes nothing: only a file in DIR's place is refused
        argv = ["reflex", "reproduce", "knee", "--out", str(out), *(["--plan"] * plan_only)]
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and says in err


def test_a_record_that_names_two_results_alike_is_refused(tmp_path, monkeypatch):
    import stumble.control.reflex.reproduce as rp

    def fit(cmd, start, before=None):
        return {"command": cmd, "wall_time_s": 60.0,
                "from": {"network": start, **({"its_fit": before} if before else {})}}

    first = fit("stumble reflex fit --walk-es placement --seed 0 --out DIR", "placement")
    second = fit("stumble reflex fit --walk-es a/network.npz --seed 1 --out DIR",
                 "a/network.npz", first)
    third = fit("stumble reflex fit --walk-es a/network.npz --seed 2 --out DIR",
                "a/network.npz", second)
    monkeypatch.setattr(rp, "_record", lambda name: ("network", third))
    with pytest.raises(InputError, match="names two stages' results alike"):
        plan("x", tmp_path)


def test_the_plan_lists_the_stages_and_runs_nothing(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["reflex", "reproduce", "placement-both", "--from", "placement-touch",
                 "--out", str(out), "--plan"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split("(")[1].split(";")[0] for ln in lines[:-1]] == [
        "tr4", "placement-foot", "placement-both"]
    assert lines[0].startswith("stage 1 of 3 (tr4; 15.3 min as recorded): stumble reflex fit")
    assert f"--out {out / 'placement-foot'}" in lines[1]
    assert "--walk-es placement-touch" in lines[2]  # the shipped file: its stages not run
    assert lines[-1].startswith("placement-both: 3 stage(s), 19.1 min as recorded")
    assert not out.exists()
