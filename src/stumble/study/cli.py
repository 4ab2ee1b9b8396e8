"""``stumble study``: its arguments and what it does (registered by ``stumble.cli``)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from stumble.study.grid import AXES, Grid, grid_from_args, load_toml
from stumble.study.runner import RUN_TIMEOUT_S

EPILOG = """\
grid values: one value (1.1), a list (0.8,1.1,1.4) or a range start:stop:count with
both ends included (0.05:0.75:15 is 15 values). A TOML FILE takes the same keys
(swing = "0.05:0.75:15", speed = [0.8, 1.1, 1.4], repeats = 5); options override it.
Running the same command again runs only what DIR does not hold yet. A study has at
most 10,000,000 runs.

example:  stumble study --swing 0.05:0.75:15 --speed 0.8,1.1,1.4 --out s/
"""


HELP_ORDER = ("controller", "strategy", "swing", "speed", "mechanism", "obstacle_height", "leg",
              "delay_scale", "delays", "strength_scale", "strength", "population", "recovery",
              "height", "mass", "sex", "contact", "seed", "duration", "timestep", "start",
              "walk_in")


def workers_arg(text: str) -> int:
    """A positive whole number of worker processes (argparse type)."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {n}")
    return n


MAX_RUN_TIMEOUT_S = 7 * 86400.0  # a week: beyond it, give 0 (no limit)


def timeout_arg(text: str) -> float:
    """Seconds in 0-``MAX_RUN_TIMEOUT_S`` (argparse type; 0: no limit)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"must be a number of seconds >= 0, got {text}")
    if v > MAX_RUN_TIMEOUT_S:
        raise argparse.ArgumentTypeError(f"{text} s is more than a week "
                                         f"({MAX_RUN_TIMEOUT_S:g} s); 0 means no limit")
    return v


def add_study_parser(sub) -> None:
    """Register ``stumble study`` on the ``stumble`` subparsers."""
    from stumble.cli import out_dir_arg
    from stumble.control.fsm_params import shipped_sets_text

    p = sub.add_parser(
        "study", help="many trips over a grid: results table, strategy and outcome maps",
        description="Run a trip for every point of a grid, on local processes or a Dask "
        "cluster. Writes DIR/results.parquet (one row per run: every scenario parameter "
        "and every summary.json field; not_set and not_set_reason when some trip could "
        "not be set at its instant), DIR/strategy_map.png, DIR/outcome_map.png and, "
        "when a delay or strength scale or the obstacle trips' height varies, "
        "DIR/fall_rate.png.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", nargs="?", type=Path, metavar="FILE", help="a TOML study file")
    p.add_argument("--out", required=True, type=out_dir_arg, metavar="DIR",
                   help="study directory")
    p.add_argument("--workers", type=workers_arg, metavar="N",
                   help="local worker processes (default: all cores; 1 runs in this process)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask distributed cluster, e.g. tcp://10.0.0.5:8786 "
                   "(pip install \"stumble[cluster]\")")
    p.add_argument("--retry-errors", action="store_true",
                   help="run again the runs whose stored row has an error (or timed out)")
    p.add_argument("--run-timeout", type=timeout_arg, default=RUN_TIMEOUT_S, metavar="S",
                   help=f"wall-time limit of one run in s; a run past it is stopped and "
                   f"recorded as a timeout row (default {RUN_TIMEOUT_S:g}; 0: no limit)")
    p.add_argument("--params", metavar="FILE|NAME",
                   help="state-machine parameters for every trip (--controller fsm): a JSON "
                   "file as scripts/tune_fsm.py --out writes it, or a shipped set "
                   f"({shipped_sets_text()}; anderson2007_walk_on and anderson2007 the "
                   "defaults with --strength anderson2007); recorded in DIR/study.json "
                   "with its SHA-256")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG maps")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    g = p.add_argument_group("grid axes (default: the `stumble trip` default)")
    for name in HELP_ORDER:
        axis = AXES[name]
        g.add_argument(f"--{axis.name.replace('_', '-')}", dest=f"axis_{axis.name}",
                       metavar="VALUES", help=axis.help)
    g.add_argument("--repeats", metavar="R",
                   help="run every grid point with the seeds 1..R (instead of --seed)")


def grid_from_namespace(args) -> Grid:
    """The study's grid: the TOML file's, with the command-line axes replacing its own."""
    base = load_toml(args.file) if args.file is not None else Grid()
    specs = {name: getattr(args, f"axis_{name}") for name in AXES}
    return base.merged(grid_from_args(specs, args.repeats))


def params_arg(path_or_name: str, grid: Grid):
    """The parameter file of ``--params`` (``fsm_params.ParamsFile``); InputError when
    the grid has a controller other than the state machines, or the file is bad."""
    from stumble.control.fsm_params import read_params
    from stumble.errors import InputError

    others = [c for c in grid.values("controller") if c != "fsm"]
    if others:
        raise InputError(f"--params is for --controller fsm in a study (the grid has "
                         f"{', '.join(others)})")
    return read_params(path_or_name)


def params_caption(out: Path) -> str:
    """The line the maps carry under their titles when the study ran with a parameter
    file (its name and SHA-256, from ``out/study.json``), else empty."""
    import json

    try:
        rec = json.loads((Path(out) / "study.json").read_text()).get("params")
    except (OSError, ValueError, AttributeError):
        return ""
    if not isinstance(rec, dict) or not rec.get("sha256"):
        return ""
    return f"state-machine parameters: {rec.get('path')} (SHA-256 {rec['sha256'][:12]})"


def run_study_cli(args) -> int:
    """``stumble study``: check the whole grid, run what is missing, report and plot."""
    from stumble.study.runner import (
        SUMMARY_COLUMNS,
        StudyInterrupted,
        iter_results,
        run_study,
        summary_table,
    )

    grid = grid_from_namespace(args)
    grid.checked_count()  # counted before anything is built
    meta = {"grid": grid.to_json(), "varying": grid.varying()}
    source = args.params if args.params is not None else grid.params  # the option wins
    params = params_arg(source, grid) if source is not None else None
    try:
        res = run_study(grid, args.out, workers=args.workers, scheduler=args.scheduler,
                        retry_errors=args.retry_errors, progress=not args.quiet,
                        metadata=meta, run_timeout_s=args.run_timeout or None,
                        params=params)
    except StudyInterrupted as e:
        print(f"stumble: {e}", file=sys.stderr)
        return 130
    print(summary_table(iter_results(res.out, SUMMARY_COLUMNS)))
    written = ["results.parquet"]
    if not args.no_plots:
        from stumble.viz.study_plots import PLOT_COLUMNS, write_study_plots

        written += write_study_plots(res.out, iter_results(res.out, PLOT_COLUMNS),
                                     params_caption(res.out))
    note = (f"; {res.other_rows} other runs in {res.out}/runs are not in this grid (kept, "
            "not in results.parquet or the maps: run their grid again to see them)"
            if res.other_rows else "")
    print(f"{res.runs} run{'' if res.runs == 1 else 's'} ({res.ran} run now, {res.before} "
          "before); wrote "
          f"{', '.join(written)} to {res.out}{note}")
    return 0
