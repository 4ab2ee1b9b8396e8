"""The ``stumble`` command line."""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import numpy as np

from stumble import __version__
from stumble.errors import InputError, StumbleError
from stumble.jsonio import dumps

# the shipped GH2010 parameter sets by name (gh2010.NAMED; here as text, so that the
# command line starts without importing the physics)
GH2010_NAMES = ("knee-2ms-dense-wide-s3 (the default: the third 2 ms touch stage, fitted "
                "on 12 of the strategy map's 45 trips, by seed 3: recovers 33 of the 45, "
                "runs at 2 ms), "
                "knee-2ms-dense-wide (the same stage by seed 0: 31 of the 45), "
                "knee (a touch stage on knee-walk; the default until 2026-12-05), "
                "knee-walk (pushed-walk "
                "refitted with the knee term), knee-foot (a touch stage on knee-walk by "
                "the foot's phase: recovers some lowering trips), knee-2ms (knee's touch "
                "stage refitted at a 2 ms step: runs at 2 ms), knee-2ms-dense (a second "
                "touch stage on knee-2ms, on 30 trips at 1.1 and 1.3 m/s: runs at 2 ms), "
                "pushed (touch stages "
                "on pushed-walk), "
                "pushed-walk (the walking fit with pushes), walk (the first walking fit), "
                "trip (trip stages on walk), expert-placement (seed003-wired: the "
                "placement network's expert) or expert-touch (a touch stage on it: "
                "recovers 25 of the 45)")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``stumble: <problem> (stumble <cmd> --help)``."""

    def error(self, message: str):
        self.exit(2, f"stumble: {message} (see `{self.prog} --help`)\n")


MIN_WALK_S = 0.05  # stumble walk --duration: a motion of a few frames at least


def _positive(kind: str):
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{kind} {text!r} is not a number") from None
        if not np.isfinite(v) or v <= 0:
            raise argparse.ArgumentTypeError(f"{kind} must be positive, got {text}")
        return v
    return parse


def out_dir_arg(text: str) -> Path:
    """An output directory (argparse type): not empty (``''`` would be the current one)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("the output directory is empty (give a path; "
                                         "'.' for the current directory)")
    return Path(text)


def seed_arg(text: str) -> int:
    """A seed (argparse type): a whole number from 0 to 2^63 - 1."""
    from stumble.trip import MAX_SEED

    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= v <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be from 0 to {MAX_SEED} (2^63 - 1), got {v}")
    return v


def _person_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--planar", action="store_true", help="the planar (sagittal) model")
    p.add_argument("--height", type=_positive("height"), default=1.75, metavar="M",
                   help="body height in m (default 1.75)")
    p.add_argument("--mass", type=_positive("mass"), default=70.0, metavar="KG",
                   help="body mass in kg (default 70)")
    p.add_argument("--sex", choices=("male", "female"), default="male",
                   help="de Leva 1996 parameter set (default male)")
    from stumble.body.contact import DEFAULT_MODE, MODES

    p.add_argument("--contact", choices=MODES, default=DEFAULT_MODE,
                   help="foot contact: SCA 2009's penalty law lumped on a few points per foot "
                   "(lumped, the default), at its 96 points per foot (points, the "
                   "reference), the same law in Python (penalty), or MuJoCo soft boxes")


def _motion_file_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", dest="motion_model", default="auto",
                   choices=("auto", "gait2392", "gait10dof18musc", "rajagopal"),
                   help=".mot/.sto: the OpenSim model family of the file, for its signs "
                   "(default: read from its coordinates and values)")
    p.add_argument("--up", default="auto", metavar="AXIS",
                   help=".bvh: the file's up axis, x y z -x -y -z (default: read from the motion)")
    p.add_argument("--forward", default="auto", metavar="AXIS",
                   help=".bvh: the axis the body faces (default: read from the motion)")


def _parser() -> argparse.ArgumentParser:
    from stumble.control.fsm_params import shipped_sets_text

    p = _Parser(
        prog="stumble",
        description="Simulate tripping while walking and the balance-recovery response.")
    p.add_argument("--version", action="version", version=f"stumble {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    m = sub.add_parser("model", help="build a human model and describe it",
                       description="Build a human model and describe it.")
    m.add_argument("--json", action="store_true", help="print one JSON object")
    _person_args(m)

    w = sub.add_parser("walk", help="play walking back on a model and write its files",
                       description="Play walking back kinematically on a model: writes "
                       "motion.csv, motion.mot, motion.bvh, events.json, joint_angles.png and "
                       "walk.mp4 to DIR.")
    w.add_argument("--out", required=True, type=out_dir_arg, metavar="DIR",
                   help="output directory")
    w.add_argument("--gait", type=Path, metavar="FILE",
                   help="an OpenSim .mot/.sto, a .bvh or a Plug-in Gait .c3d motion (default: "
                   "the embedded subject01 reference gait)")
    _motion_file_args(w)
    w.add_argument("--as-recorded", action="store_true",
                   help="--gait: play the file's joint angles exactly, at its own sample "
                   "times (no foot planting, no turning onto +x)")
    w.add_argument("--speed", type=float, metavar="V",
                   help="walking speed in m/s, 0.7-1.6 (reference gait only; default: the "
                   "subject's 1.10 m/s)")
    w.add_argument("--duration", type=_positive("duration"), metavar="S",
                   help="seconds to play (default 4 for the reference, the whole file otherwise)")
    w.add_argument("--no-video", action="store_true", help="skip walk.mp4")
    _person_args(w)

    t = sub.add_parser("trip", help="walk, trip and recover (or fall); write its files",
                       description="Simulate one trip: writes summary.json, timeseries.csv, "
                       "motion.mot, motion.bvh (reflex: muscles.sto), trajectories.png, "
                       "filmstrip.png and trip.mp4 to DIR.")
    t.add_argument("--out", required=True, type=out_dir_arg, metavar="DIR",
                   help="output directory")
    t.add_argument("--controller", choices=("fsm", "reflex", "gh2010"), default="fsm",
                   help="fsm: the state-machine controllers of SCA 2009 on the 3D human; "
                   "reflex: the neuromuscular reflex network of seed 003 on the planar "
                   "musculoskeletal human; gh2010: Geyer & Herr 2010's reflexes on that "
                   "body (the reflex controllers' strategy emerges)")
    t.add_argument("--params", type=Path, metavar="FILE",
                   help="gh2010 controller: a gh2010.json, or a shipped set by name: "
                   f"{GH2010_NAMES}; fsm: a JSON of tuned "
                   "targets and gains (scripts/tune_fsm.py --out) or a shipped set by "
                   f"name: {shipped_sets_text()} (with --strength anderson2007 the "
                   "default is anderson2007_walk_on, or anderson2007 under --recovery "
                   "step; docs/trips.md, 'Parameter sets', says what each is)")
    t.add_argument("--network", type=Path, metavar="FILE",
                   help="reflex controller: a network.npz from `stumble reflex fit`, or a "
                   "shipped network: past-support (the default: past-swing with the "
                   "support leg's GLU on and the tripped leg's VAS off after a touch of "
                   "the foot behind; walks within 10 deg and recovers trips of both "
                   "strategies past the box), "
                   "past-swing (past-foot with the other leg swung through after a touch "
                   "of the foot ahead), placement-both "
                   "(the default before 2026-12-07: placement-touch's "
                   "response for the foot behind, placement-foot's for the foot ahead), "
                   "closed-loop (the identification refined by DAgger), placement "
                   "(refined from a placing "
                   "expert: walks closer to the recording), placement-es (placement refined "
                   "by CMA-ES), placement-walk (placement-es held within 10 deg at every "
                   "joint: closest to the recording), placement-touch (placement-walk with "
                   "a touch response: recovers early-swing trips), placement-foot (its "
                   "response by the foot's place), past-foot (the same fitted with a "
                   "recovery past the box) or open-loop "
                   "(seed 003's "
                   "identification alone)")
    t.add_argument("--no-trunk-balance", action="store_true",
                   help="reflex controller: without the stance hips' trunk-lean reflex "
                   "(our addition to seed 003; see docs/reflex.md)")
    t.add_argument("--strategy", choices=("auto", "elevating", "lowering"), default="auto",
                   help="auto: elevating up to 0.5 of swing, lowering above (default auto)")
    t.add_argument("--swing", type=float, default=0.2, metavar="F",
                   help="trip instant as a fraction of the tripped leg's swing, 0.05-0.9")
    t.add_argument("--speed", type=float, default=None, metavar="V",
                   help="walking speed in m/s, 0.7-1.6 (default: the population's, 1.2 "
                   "young, 1.17 older)")
    t.add_argument("--strength", choices=("fixed", "anderson2007"), default="fixed",
                   help="servo torque limits (fsm): fixed (default) or anderson2007, human "
                   "strength by joint angle and velocity (Anderson et al. 2007)")
    t.add_argument("--recovery", choices=("step", "walk_on"), default="walk_on",
                   help="what recovered means (fsm): walk_on, still walking upright at "
                   "the end of --duration, 4 steps or more after the recovery step "
                   "(default); step, 1 s after the recovery step upright over the feet, "
                   "where the run stops (with the same default set: --params step for the "
                   "set tuned for it)")
    t.add_argument("--population", choices=("young", "older"), default="young",
                   help="young (default) or older adults (fsm): strength, response "
                   "latencies, torque development and walking speed of healthy older "
                   "adults")
    t.add_argument("--mechanism", choices=("force", "obstacle"), default=None,
                   help="force: SCA 2009 eq. 2-3 on the swing toe; obstacle: a rigid box "
                   "(default: force for fsm, obstacle for reflex, as each seed)")
    t.add_argument("--obstacle-height", type=float, default=None, metavar="M",
                   help="--mechanism obstacle: its height in m (default 0.10)")
    t.add_argument("--leg", choices=("left", "right"), default="left", help="tripped leg")
    t.add_argument("--reference", type=Path, metavar="FILE",
                   help="a recorded trip (.mot/.sto/.bvh/.c3d) for the joint-pitch RMSE")
    t.add_argument("--reference-align", choices=("swing", "time"), default=None,
                   help="with --reference: swing (default), the reference's trip is its "
                   "tripped leg's first toe-off plus --swing of that swing; time, the "
                   "file's time 0 is the trip")
    _motion_file_args(t)
    t.add_argument("--seed", type=seed_arg, default=0,
                   help="0 (default): the recorded walk as it is; another seed perturbs the "
                   "initial joint angles (SD 0.5 deg) and velocities; deterministic")
    t.add_argument("--duration", type=float, default=None, metavar="S",
                   help="seconds of physics after the trip at most (default 6 for fsm "
                   "walking on, else 3)")
    t.add_argument("--start", choices=("playback", "own"), default=None,
                   help="playback: the recorded walk up to the trip instant, the controller "
                   "from there (the seeds'; default fsm; seed 003's CASE 1 and 2 with "
                   "reflex); own: the controller walks from right heel strike and is tripped "
                   "in its own gait (default reflex, gh2010; reflex controllers only)")
    t.add_argument("--walk-in", type=float, default=None, metavar="S",
                   help="--start own: seconds the controller walks before the trip's swing "
                   "(default 4)")
    t.add_argument("--no-video", action="store_true", help="skip filmstrip.png and trip.mp4")
    _person_args(t)
    from stumble.study.cli import add_study_parser
    from stumble.validate import add_validate_parser

    add_study_parser(sub)
    add_validate_parser(sub)

    from stumble.control.reflex.cli import add_reflex_parser

    add_reflex_parser(sub, _Parser)
    return p


def _build(args):
    from stumble.body import build

    return build(planar=args.planar, height_m=args.height, mass_kg=args.mass, sex=args.sex,
                 contact=args.contact)


def cmd_model(args) -> int:
    """``stumble model``: describe the model."""
    d = _build(args).describe()
    if args.json:
        print(dumps(d))
    else:
        print(f"{d['model']} human: {d['dof']} DOF ({d['internal_dof']} internal), "
              f"nq {d['nq']}, nu {d['nu']}, {d['mass_kg']:.1f} kg, {d['height_m']} m")
        for name, mass in d["segments"].items():
            print(f"  {name:14s} {mass:7.3f} kg")
    return 0


def _numbers(text: str | None, flag: str, lo: float, hi: float, what: str,
             unit: str = "") -> tuple[float, ...]:
    """``FLAG V[,V...]``: numbers within [lo, hi]; InputError naming the flag otherwise."""
    import math

    if text is None:
        return ()
    out = []
    for part in text.split(","):
        try:
            v = float(part)
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and lo <= v <= hi):
            raise InputError(f"{flag} takes {what} of {lo:g}-{hi:g}{unit} separated by "
                             f"commas, got {text!r}")
        out.append(v)
    return tuple(out)


def _notes(notes) -> None:
    """Print each one-line note about an input file on stderr."""
    for note in notes:
        print(f"stumble: note: {note}", file=sys.stderr)


def _read_gait_file(args):
    from stumble.gait.files import read_motion

    return read_motion(args.gait, planar=args.planar, model=args.motion_model, up=args.up,
                       forward=args.forward)


def _cycle_curves(pb, names):
    """Mean and SD per coordinate over each side's complete strides, 0-100 % (101 points)."""
    pct = np.linspace(0.0, 100.0, 101)
    mean, sd, toe_off = {}, {}, {}
    for side in ("r", "l"):
        hs = pb.events.heel_strike_s[side]
        strides = list(itertools.pairwise(hs))
        for name in names:
            key = f"{name}_{side}"
            if key not in pb.coordinates:
                continue
            series = pb.coordinates[key]
            if strides:
                rows = [np.interp(a + pct / 100.0 * (b - a), pb.time_s, series)
                        for a, b in strides]
            else:  # shorter than a stride: fold on the stride from this foot's heel strike
                other = pb.events.heel_strike_s["l" if side == "r" else "r"]
                start = hs[0] if hs else (other[0] - 0.5 * pb.stride_s if other else 0.0)
                ph = ((pb.time_s - start) / pb.stride_s % 1.0) * 100.0
                order = np.argsort(ph)
                rows = [np.interp(pct, ph[order], series[order], period=100.0)]
            mean[key] = np.degrees(np.mean(rows, axis=0))
            sd[key] = np.degrees(np.std(rows, axis=0))
        offs = [np.mean([(x - a) / (b - a) for x in pb.events.toe_off_s[side] if a < x < b])
                for a, b in strides if any(a < x < b for x in pb.events.toe_off_s[side])]
        if not strides:  # the toe-offs that follow a heel strike within a stride
            offs = [(x - a) / pb.stride_s for a in hs for x in pb.events.toe_off_s[side]
                    if 0 < x - a < pb.stride_s]
        if offs:
            toe_off[side] = 100.0 * float(np.mean(offs))
    return pct, mean, sd, toe_off


def _title(pb, model: str) -> str:
    src = "reference gait (OpenSim subject01)" if pb.source.startswith("reference") else (
        pb.source.removeprefix("file: "))
    return f"{model.upper()} model, {src}, {pb.speed_m_per_s:.2f} m/s"


def cmd_walk(args) -> int:
    """``stumble walk``: play a gait back and write motion, events, plot and video."""
    from stumble.gait.reference import check_speed

    if args.gait is not None and args.speed is not None:
        raise InputError("--speed applies to the embedded reference gait; a --gait file plays "
                         "at its own speed")
    if args.speed is not None:
        check_speed(args.speed)
    if args.duration is not None and args.duration < MIN_WALK_S:
        raise InputError(f"--duration {args.duration:g} s is too short to write a motion "
                         f"(at least {MIN_WALK_S:g} s)")
    if args.gait is None and (args.as_recorded or args.motion_model != "auto"
                              or args.up != "auto" or args.forward != "auto"):
        raise InputError("--as-recorded, --model, --up and --forward apply to a --gait file")
    motion = _read_gait_file(args) if args.gait is not None else None  # before the model
    from stumble.gait.playback import walk
    from stumble.gait.writers import write_bvh, write_mot, write_motion_csv
    from stumble.jsonio import write_json
    from stumble.outputs import VIDEO_FPS, prepare_dir
    from stumble.viz.plots import plot_joint_angles

    body = _build(args)
    if motion is not None:
        from stumble.gait.files import play_motion

        pb = play_motion(body, motion, args.duration, as_recorded=args.as_recorded)
    else:
        pb = walk(body, args.speed, duration_s=args.duration or 4.0)
    _notes(pb.notes)  # after playing: a refused file gives its one error line only
    out = prepare_dir(args.out)
    write_motion_csv(out / "motion.csv", pb)
    write_mot(out / "motion.mot", body, pb.time_s, pb.qpos)
    write_bvh(out / "motion.bvh", body, pb.time_s, pb.qpos)
    stance = pb.events.stance_fraction()
    notes = list(pb.notes)
    if not np.isfinite(stance):
        stance = pb.events.stance_fraction_from(pb.stride_s)
        notes.append("stance fraction from heel strike to toe-off over the estimated stride"
                     if stance is not None else "stance fraction: no heel strike followed "
                     "by a toe-off")
    events = {**pb.events.to_json(),
              "speed_m_per_s": round(pb.speed_m_per_s, 4),
              "stride_s": round(pb.stride_s, 4),
              "stance_fraction": None if stance is None else round(stance, 4),
              "source": pb.source,
              "model": "planar" if body.planar else "3d",
              "retarget": pb.retarget,
              "notes": notes}
    write_json(out / "events.json", events)
    # plots and video show each touchdown's planting step spread over 80 ms; the motion
    # files keep it, so they read back as written (Playback.shown, TOUCHDOWN_BLEND_S)
    shown = pb.shown()
    pct, mean, sd, toe_off = _cycle_curves(shown, ["hip_flexion", "knee_angle",
                                                   "ankle_angle"])
    plot_joint_angles(out / "joint_angles.png", pct, mean, events={"toe_off_percent": toe_off},
                      title=_title(pb, events["model"]), spread_deg=sd)
    written = ["motion.csv", "motion.mot", "motion.bvh", "events.json", "joint_angles.png"]
    if not args.no_video:
        from stumble.viz.render import render_video, video_available

        ok, why = video_available()
        if ok:
            step = max(1, round(1.0 / (VIDEO_FPS * float(np.mean(np.diff(shown.time_s))))))
            frames = shown.qpos[::step]
            fps = 1.0 / (step * float(np.mean(np.diff(shown.time_s))))
            overlay = [f"t = {t:5.2f} s  played back at {shown.speed_m_per_s:.2f} m/s"
                       for t in shown.time_s[::step]]
            render_video(out / "walk.mp4", body.model, frames, fps, overlay=overlay,
                         progress=sys.stderr.isatty())
            written.append("walk.mp4")
        else:
            print(f"stumble: {why}", file=sys.stderr)
    stance_text = "n/a" if stance is None else f"{stance:.3f}"
    print(f"walked {pb.time_s[-1]:.2f} s at {pb.speed_m_per_s:.2f} m/s (stride "
          f"{pb.stride_s:.3f} s, stance {stance_text}); wrote {', '.join(written)} to {out}")
    return 0


def _network_arg(path: Path):
    """The network of ``--network``: a file, or a shipped one by name (``NETWORK_NAMES``)."""
    from stumble.control.reflex.identify import NETWORK_NAMES, default_network
    from stumble.control.reflex.network import Network

    if str(path) in NETWORK_NAMES and not path.exists():
        return default_network(str(path))
    return Network.load(path)


def cmd_trip(args) -> int:
    """``stumble trip``: one trip, its summary, time series, plots and video."""
    import time

    t_command = time.perf_counter()
    from stumble.analysis import NOT_PAST
    from stumble.outputs import (
        prepare_dir,
        trip_motion,
        write_media,
        write_motion_files,
        write_summary,
        write_timeseries,
    )
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    if args.planar and args.controller == "fsm":
        raise InputError("the fsm controller drives the 3D model; the reflex controller "
                         "uses the planar one (--controller reflex)")
    if (args.network or args.no_trunk_balance) and args.controller != "reflex":
        raise InputError("--network and --no-trunk-balance are for --controller reflex")
    if args.params and args.controller == "reflex":
        raise InputError("--params is for --controller fsm or gh2010")
    from stumble.trip import POPULATIONS

    speed = (POPULATIONS[args.population].preferred_speed_m_per_s if args.speed is None
             else args.speed)
    mechanism = args.mechanism or ("force" if args.controller == "fsm" else "obstacle")
    if args.obstacle_height is not None and mechanism != "obstacle":
        raise InputError("--obstacle-height is for --mechanism obstacle")
    if args.reference_align is not None and args.reference is None:
        raise InputError("--reference-align applies to a --reference file")
    scenario = Scenario(swing_fraction=args.swing, speed_m_per_s=speed,
                        strength_model=args.strength, population=args.population,
                        recovery=args.recovery, leg=args.leg, mechanism=mechanism,
                        **({} if args.obstacle_height is None
                           else {"obstacle_height_m": args.obstacle_height}),
                        controller=args.controller,
                        strategy=args.strategy, seed=args.seed, height_m=args.height,
                        mass_kg=args.mass, sex=args.sex, contact=args.contact,
                        duration_after_trip_s=args.duration, start=args.start,
                        **({} if args.walk_in is None else {"walk_in_s": args.walk_in}))
    gh2010 = None
    if args.params and args.controller == "gh2010":  # loaded first: its step is the default
        from stumble.control.reflex.gh2010 import load_params

        gh2010 = load_params(args.params)
    scenario = scenario.validated(None if gh2010 is None else gh2010.timestep_s)
    if args.walk_in is not None and scenario.start != "own":
        raise InputError("--walk-in is for --start own")
    if args.reference is None and (args.motion_model != "auto" or args.up != "auto"
                                   or args.forward != "auto"):
        raise InputError("--model, --up and --forward apply to a --reference file")
    reference = _load_reference_trip(args, scenario) if args.reference else None
    network = None
    if args.network:
        from stumble.control.reflex.network import steps_per_tick

        network = _network_arg(args.network)
        steps_per_tick(scenario.timestep_s, network.topology.rate_hz)
    fsm, fsm_record = None, None
    if args.controller == "fsm":  # the set that runs, named in summary.json
        from stumble.control.fsm_params import DEFAULT_SETS, read_params

        read = read_params(args.params if args.params else
                           DEFAULT_SETS[(scenario.strength_model, scenario.recovery)])
        fsm = read.params
        fsm_record = {"path": read.name, "sha256": read.sha256,
                      "default": not args.params}
    out = prepare_dir(args.out)  # and writable: checked before the simulation
    result = simulate_trip(scenario, params=fsm, reference=reference, network=network,
                           trunk_balance=not args.no_trunk_balance, gh2010=gh2010)
    if fsm_record is not None:
        result.summary["fsm_params"] = fsm_record
    write_summary(out, result)
    write_timeseries(out, result)
    time_s, qpos = trip_motion(result)
    written = ["summary.json", "timeseries.csv",
               *write_motion_files(out, result.body, time_s, qpos, result.recording),
               *write_media(out, result, not args.no_video, sys.stderr.isatty())]
    s = result.summary
    if s.get("trip_time_s") is None:  # --start own: the walker never reached the trip
        print(f"no trip: the {s['controller']} walker {s['stop_reason']} "
              f"({s['walk_in']['walked_s']:.2f} s into its own walk); wrote "
              f"{', '.join(written)} to {out}")
        return 0
    outcome = ("diverged" if s["diverged"] else "recovered" if s["recovered"]
               else "fell" if s["fell"]
               else "did not recover: walking, but not past the obstacle"
               if s["stop_reason"] == NOT_PAST
               else "did not recover within the time")
    strategy = s["strategy"] or "no"
    variant = f" ({s['variant']})" if s["variant"] else ""  # none if no recovery step
    if s.get("recovery") == "walk_on" and s["controller"] == "fsm" and s.get(
            "steps_after_recovery_step") is not None:  # what walking on came to
        outcome += f" ({s['steps_after_recovery_step']} steps after the recovery step)"
    total = time.perf_counter() - t_command
    print(f"{strategy} strategy{variant}: {outcome}; simulated "
          f"{s['sim_time_s']:.2f} s in {s['wall_time_s']:.2f} s ({total:.1f} s in all, "
          f"{'files' if args.no_video else 'files and video'} included); wrote "
          f"{', '.join(written)} to {out}")
    return 0


def _load_reference_trip(args, scenario) -> dict:
    """Pitch angles (deg) of a recorded trip, time 0 at its trip (``--reference-align``)."""
    from stumble.gait.files import align_reference, read_motion

    motion = read_motion(args.reference, planar=args.controller == "reflex",
                         model=args.motion_model, up=args.up, forward=args.forward)
    ref = align_reference(motion, scenario, args.reference_align or "swing", args.duration)
    _notes(ref.notes)
    return {"time_s": ref.time_s, **{k: np.degrees(v) for k, v in ref.columns.items()}}


def _mujoco_gl_error() -> str | None:
    """MuJoCo refuses to import under a ``MUJOCO_GL`` it does not know: that, as one line."""
    try:
        import mujoco  # noqa: F401  (reads MUJOCO_GL once, at import)
    except RuntimeError as e:
        if "MUJOCO_GL" not in str(e):
            raise
        return (f"{e} (MuJoCo takes egl, osmesa, glx or glfw on Linux; unset it, "
                "or MUJOCO_GL=off for no video)")
    return None


def main(argv: list[str] | None = None) -> int:
    """Entry point: run a subcommand; user errors become one line on stderr, exit 2."""
    gl_error = _mujoco_gl_error()
    if gl_error:
        print(f"stumble: {gl_error}", file=sys.stderr)
        return 2
    parser = _parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # named with the subcommand whose help lists what it takes
        words = [w for w in ("stumble", args.command, getattr(args, "reflex_command", None))
                 if w]
        print(f"stumble: unrecognized arguments: {' '.join(extra)} (see `{' '.join(words)} "
              "--help`)", file=sys.stderr)
        return 2
    if args.command is None:
        parser.print_help()
        return 0
    from stumble.control.reflex.cli import cmd_reflex
    from stumble.study.cli import run_study_cli
    from stumble.validate import run_validate_cli

    handlers = {"model": cmd_model, "walk": cmd_walk, "trip": cmd_trip, "reflex": cmd_reflex,
                "study": run_study_cli, "validate": run_validate_cli}
    try:
        return handlers[args.command](args)
    except StumbleError as e:
        print(f"stumble: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("stumble: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
