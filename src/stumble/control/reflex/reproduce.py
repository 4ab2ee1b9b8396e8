"""Re-running the recorded chain of fits that made a shipped reflex parameter set.

Every closed-loop fit (``stumble reflex fit``) records in its output its command, its
start (a shipped name or the path of the stage before, with that file's own record) and
its wall time, so a shipped set carries the whole chain of fits that made it. This module
reads that chain back, oldest stage first, and runs it as one job: each stage's ``--out``
a directory of its own under the job's, each start the output of the stage before
(rather than the shipped file of that name), a response taken from another network
(``--ahead-from``) made by its own chain first (stages the two chains share run once).
After each stage whose result is shipped too, the parameters are compared with the
shipped ones, value for value: the same machine and versions give them bit for bit (a
fit is deterministic for its seed); another machine may not, and says so.

Where a chain starts: from the paper's gains. Geyer & Herr's default is five fits (32.5
min on 2 workers); the networks start from ``placement``, DAgger's network, whose file
records no command but whose command is known (``ROOTS``: ``reflex fit --closed-loop
--seed 0 --expert expert-placement``), after its expert's five fits.
"""

from __future__ import annotations

import json
import math
import shlex
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from stumble.errors import InputError

START_OPTIONS = ("--params", "--walk-es")  # the option naming a fit's start
AHEAD_OPTION = "--ahead-from"
EXPERT_OPTION = "--expert"  # DAgger's expert (a seed003-wired Geyer & Herr set)


@dataclass
class Stage:
    """One recorded fit: its command (as recorded, ``--out DIR``), what it started from
    (a shipped name, a path, or None: the paper's gains), the network a response was
    taken from (``--ahead-from``), its recorded minutes, and ``tag``: the name of the
    directory its result goes to (the shipped name of that result, or the recorded
    directory's name)."""

    command: str
    start: str | None
    minutes: float
    tag: str = ""
    ahead_from: str | None = None
    expert: str | None = None  # DAgger's expert, a shipped set made by its own chain first
    kind: str = ""  # what it fits: ``gh2010`` or ``network`` (set by ``plan``)
    argv: list[str] = field(default_factory=list)  # the command to run (set by ``plan``)


# Shipped networks that record no fit command but whose command is known and re-runs
# them bit for bit: ``placement``, DAgger from the placing expert (docs/reflex-network.md), where
# the CMA-ES chains of the network start (re-run
# 2026-12-05, fourth session: the shipped weights and trunk balance bit for bit, 50.6
# min on 2 workers with other work on the machine; fifth session, its training shared
# by the workers (``dagger.SetPool``): bit for bit again, 20.5 min on 2 workers, idle;
# 2026-12-06, thirteenth session, its batch pass compiled: 10.4 min on the Intel Xeon).
# A chain that starts from one runs it first, its expert's chain before it.
ROOTS = {"placement": Stage("stumble reflex fit --closed-loop --seed 0 --expert "
                            "expert-placement --no-video --out DIR", None, 20.5,
                            expert="expert-placement"),
         # DAgger by the cross-entropy through pushes (2026-12-05, eighth session)
         "cross-entropy": Stage("stumble reflex fit --closed-loop --seed 0 --expert "
                                "expert-placement --loss cross-entropy --pushes "
                                "--no-video --out DIR", None, 13.8,
                                expert="expert-placement"),
         # the same by seed 1: its best pass (4) walks through both pushes (ninth session;
         # its passes 0-4 re-run that session gave the same costs, pass 4's 2.9)
         "cross-entropy-s1": Stage("stumble reflex fit --closed-loop --seed 1 --expert "
                                   "expert-placement --loss cross-entropy --pushes "
                                   "--no-video --out DIR", None, 25.0,
                                   expert="expert-placement")}


def _record(name: str) -> tuple[str, dict | None]:
    """(kind, fit record) of a shipped set: kind ``gh2010`` or ``network``."""
    from stumble.control.reflex.gh2010 import NAMED, named_file
    from stumble.control.reflex.identify import NETWORK_NAMES, default_network

    if name in NAMED:
        data = json.loads(named_file(name).read_text())
        return "gh2010", data.get("fit")
    if name in NETWORK_NAMES:
        return "network", (default_network(name).info or {}).get("fit")
    names = sorted(NAMED) + sorted(NETWORK_NAMES)
    raise InputError(f"{name!r} is not a shipped parameter set or network (one of: "
                     f"{', '.join(names)})")


def stages(fit: dict | None) -> list[Stage]:
    """The stages of a fit record, oldest first (``fit.from.its_fit`` back to the
    first); a record without a command (an identification, DAgger) ends the chain."""
    out = []
    while isinstance(fit, dict) and fit.get("command"):
        src = fit.get("from")
        src = src if isinstance(src, dict) else {}
        start = src.get("params") or src.get("network")
        ahead = fit.get("ahead_from")
        out.append(Stage(fit["command"], None if start is None else str(start),
                         (fit.get("wall_time_s") or 0.0) / 60.0,
                         ahead_from=(ahead or {}).get("network") if isinstance(ahead, dict)
                         else None))
        fit = src.get("its_fit")
    return out[::-1]


def _shipped() -> set[str]:
    """Every shipped set's and network's name."""
    from stumble.control.reflex.gh2010 import NAMED
    from stumble.control.reflex.identify import NETWORK_NAMES

    return set(NAMED) | set(NETWORK_NAMES)


def _tag(start: str) -> str:
    """The directory name of the stage that made ``start``: a shipped name as it is, a
    recorded path by its directory's name (``tr3/network.npz``: ``tr3``)."""
    p = Path(start)
    return p.parent.name if p.suffix in (".npz", ".json") and p.parent.name else p.name


def plan(name: str, root: Path) -> tuple[str, list[Stage]]:
    """(kind, the stages to run in order) for the shipped set ``name``, each with its
    ``argv`` pointing at ``root``: ``--ahead-from`` chains first, shared stages once."""
    kind, fit = _record(name)
    chain = stages(fit)
    if name in ROOTS:
        chain = [replace(ROOTS[name])]
    elif chain and chain[0].start in ROOTS:
        chain.insert(0, replace(ROOTS[chain[0].start]))
    if not chain:
        raise InputError(f"{name!r} records no fit command to re-run (an identification "
                         "or a DAgger network: see docs/reflex.md)")
    out_file = _out_file(kind)
    for i, st in enumerate(chain):
        st.kind = kind
        nxt = chain[i + 1].start if i + 1 < len(chain) else None
        st.tag = name if i + 1 == len(chain) else _tag(nxt) if nxt else f"stage{i + 1}"
    tags = [st.tag for st in chain]
    if len(set(tags)) < len(tags):
        raise InputError(f"{name!r}: its record names two stages' results alike "
                         f"({', '.join(tags)}); run its commands by hand")
    done: list[Stage] = []
    for i, st in enumerate(chain):
        for need in (st.expert, st.ahead_from):
            if not need:
                continue
            if need not in _shipped():
                raise InputError(f"{name!r}: stage {st.tag} takes {need!r}, which is not "
                                 "shipped")
            for sub in plan(need, root)[1]:
                if not any(d.argv == sub.argv for d in done):
                    done.append(sub)
        prev = chain[i - 1].tag if i else None
        st.argv = _argv(st, prev, root, out_file)
        if not any(d.argv == st.argv for d in done):
            done.append(st)
    return kind, done


def _out_file(kind: str) -> str:
    """The file a fit of ``kind`` writes its result to."""
    return "gh2010.json" if kind == "gh2010" else "network.npz"


def _argv(st: Stage, prev: str | None, root: Path, out_file: str) -> list[str]:
    """The stage's command as arguments of ``stumble``: its start the stage before's
    output (the first stage's start, a shipped set, as recorded), ``--ahead-from`` that
    network's output, ``--out`` its own directory."""
    words = shlex.split(st.command)
    if words and words[0] == "stumble":
        words = words[1:]
    out = []
    i = 0
    while i < len(words):
        w = words[i]
        val = words[i + 1] if i + 1 < len(words) else None
        if w in START_OPTIONS and val is not None and prev is not None:
            out += [w, str(root / prev / out_file)]
            i += 2
        elif w == AHEAD_OPTION and val is not None:
            out += [w, str(root / _tag(val) / out_file)]
            i += 2
        elif w == EXPERT_OPTION and val is not None:
            out += [w, str(root / _tag(val) / "gh2010.json")]
            i += 2
        elif w == "--out" and val is not None:
            out += [w, str(root / st.tag)]
            i += 2
        else:
            out.append(w)
            i += 1
    return out


def same_as_shipped(kind: str, path: Path, name: str) -> tuple[bool, str]:
    """Whether the result at ``path`` has the shipped set ``name``'s parameters, value
    for value; (verdict, the first difference or "")."""
    if kind == "gh2010":
        from stumble.control.reflex.gh2010 import load_params

        a, b = asdict(load_params(str(path))), asdict(load_params(name))
        for k in b:
            x, y = a.get(k), b[k]
            if not (x == y or (isinstance(x, float) and isinstance(y, float)
                               and math.isnan(x) and math.isnan(y))):
                return False, f"{k}: {x!r} against {y!r}"
        return True, ""
    from stumble.control.reflex.identify import default_network
    from stumble.control.reflex.network import Network

    a, b = Network.load(path), default_network(name)
    for k in ("w", "b", "v", "c", "mean", "std"):
        x, y = getattr(a, k), getattr(b, k)
        if x.shape != y.shape or not np.array_equal(x, y):
            return False, f"weights {k} differ"
    for k in ("balance", "touch_response"):
        if (a.info or {}).get(k) != (b.info or {}).get(k):
            return False, f"{k} differs"
    return True, ""


def jobs(name: str, root: Path, start_after: str | None = None) -> tuple[str, list[Stage]]:
    """(kind, the stages ``run`` would run in order) for ``name`` into ``root``, from
    after the shipped result ``start_after`` when given (nothing is run or written)."""
    kind, todo = plan(name, Path(root))
    if start_after is not None:
        shipped = _shipped()
        tags = [s.tag for s in todo]
        if start_after not in tags or start_after == name:
            raise InputError(f"--from {start_after!r}: not a shipped result on the way to "
                             f"{name!r} (those are: "
                             f"{', '.join(t for t in tags[:-1] if t in shipped) or 'none'})")
        todo = _after(todo, start_after, shipped)
    return kind, todo


def run(name: str, root: Path, start_after: str | None = None,
        runner: Callable[[list[str]], int] | None = None, log=sys.stderr) -> dict:
    """Run the chain of ``name`` into ``root`` (stages whose output is there already are
    kept: a stopped job resumes); ``start_after``: a shipped result of the chain to start
    from (its own stages are not run: later stages start from the shipped file). Writes
    ``root/reproduce.json`` after every stage; returns it."""
    if runner is None:
        from stumble.cli import main as runner
    root = Path(root)
    kind, todo = jobs(name, root, start_after)
    shipped = _shipped()
    root.mkdir(parents=True, exist_ok=True)
    report = {"name": name, "kind": kind, "from": start_after, "stages": []}
    t_all = time.perf_counter()
    for i, st in enumerate(todo, 1):
        result = root / st.tag / _out_file(st.kind)  # (an expert's chain: gh2010)
        entry = {"stage": i, "of": len(todo), "tag": st.tag,
                 "command": "stumble " + shlex.join(st.argv),
                 "recorded_minutes": round(st.minutes, 2)}
        if result.exists():
            entry["minutes"] = None
            entry["note"] = "its result was there already: kept"
            print(f"reproduce: stage {i} of {len(todo)} ({st.tag}): done already", file=log)
        else:
            print(f"reproduce: stage {i} of {len(todo)} ({st.tag}; {st.minutes:.1f} min as "
                  f"recorded): stumble {shlex.join(st.argv)}", file=log, flush=True)
            tic = time.perf_counter()
            rc = runner(list(st.argv))
            entry["minutes"] = round((time.perf_counter() - tic) / 60.0, 2)
            if rc == 130:  # the stage was interrupted (Ctrl-C): so is the job
                _write(root, report)
                raise KeyboardInterrupt
            if rc != 0 or not result.exists():
                entry["error"] = f"exit status {rc}"
                report["stages"].append(entry)
                _write(root, report)
                raise InputError(f"reproduce: stage {i} ({st.tag}) failed (exit status "
                                 f"{rc}); its command is in {root / 'reproduce.json'}")
        if st.tag in shipped:
            same, why = same_as_shipped(st.kind, result, st.tag)
            entry["same_as_shipped"] = same
            if not same:
                entry["difference"] = why
            print(f"reproduce: {st.tag}: " + ("the shipped parameters, bit for bit" if same
                                              else f"differs from the shipped file ({why})"),
                  file=log, flush=True)
        report["stages"].append(entry)
        _write(root, report)
    report["minutes"] = round((time.perf_counter() - t_all) / 60.0, 2)
    report["result"] = str(root / name / _out_file(kind))
    report["same_as_shipped"] = report["stages"][-1].get("same_as_shipped")
    _write(root, report)
    return report


def _refs(st: Stage) -> list[tuple[int, str]]:
    """(argv index, tag) of every result the stage starts from (its start, its
    ``--ahead-from``) that a stage of the job makes."""
    return [(j + 1, Path(st.argv[j + 1]).parent.name) for j, w in enumerate(st.argv[:-1])
            if w in (*START_OPTIONS, AHEAD_OPTION, EXPERT_OPTION)]


def _after(todo: list[Stage], start_after: str, shipped: set[str]) -> list[Stage]:
    """The stages that ``start_after`` does not lead from: it and every stage it was made
    from are not run, and a kept stage that starts from one of their results starts from
    that result's shipped file (by name)."""
    made = {s.tag: s for s in todo}
    skip, stack = set(), [start_after]
    while stack:  # start_after and everything upstream of it
        t = stack.pop()
        if t in skip or t not in made:
            continue
        skip.add(t)
        stack += [r for _j, r in _refs(made[t])]
    keep = []
    for st in todo:
        if st.tag in skip:
            continue
        argv = list(st.argv)
        for j, t in _refs(st):
            if t in skip:
                if t not in shipped:
                    raise InputError(f"--from {start_after!r}: stage {st.tag} starts from "
                                     f"{t}, which is not run and not shipped")
                argv[j] = t  # the shipped file, by its name
        keep.append(replace(st, argv=argv))
    return keep


def _write(root: Path, report: dict) -> None:
    from stumble.jsonio import write_json

    write_json(root / "reproduce.json", report)
