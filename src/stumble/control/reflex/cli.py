"""The ``stumble reflex`` commands: ``walk``, ``fit`` and ``reproduce``, the reflex
controllers' command line (their parser, and each command from its parsed arguments)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from stumble.cli import (
    GH2010_NAMES,
    _network_arg,
    _notes,
    _numbers,
    _positive,
    out_dir_arg,
    seed_arg,
)
from stumble.errors import InputError

MAX_WEIGHT = 1e4  # an objective's weight or cost: beyond it the sums overflow to inf


def _reflex_controller(value: str) -> str:
    """``--controller``: ``reflex`` (``stumble trip``'s name for the network) is ``network``."""
    return "network" if value == "reflex" else value


def _weight(text: str) -> float:
    """An objective's weight or cost (argparse type): a finite number in 0-``MAX_WEIGHT``."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(v) and 0.0 <= v <= MAX_WEIGHT):
        raise argparse.ArgumentTypeError(f"must be a number in 0-{MAX_WEIGHT:g}, got {text}")
    return v


def _start_speeds(text: str | None) -> tuple[float, ...]:
    """``--starts V[,V...]``: walking speeds (m/s) of the reference walk's range."""
    from stumble.gait.reference import SPEED_RANGE_M_PER_S

    lo, hi = SPEED_RANGE_M_PER_S
    return _numbers(text, "--starts", lo, hi, "speeds", " m/s")


def _delay_scales(text: str | None) -> tuple[float, ...]:
    """``--delay-walks K[,K...]``: delay scales of 0.5-3."""
    return _numbers(text, "--delay-walks", 0.5, 3.0, "delay scales")


def _network_record(arg: str):
    """A network named on the command line (a file, or a shipped name) and what a fit
    records of it: ``{"network": as named, "sha256": of its file}``."""
    import hashlib
    from importlib import resources

    from stumble.control.reflex.identify import NETWORK_NAMES

    path = Path(arg)
    net = _network_arg(path)
    data = (path.read_bytes() if path.exists() or arg not in NETWORK_NAMES
            else (resources.files("stumble.control.reflex") / "data"
                  / NETWORK_NAMES[arg]).read_bytes())
    return net, {"network": str(arg), "sha256": hashlib.sha256(data).hexdigest()}


class _Progress:
    """A one-line progress bar on stderr (only on a terminal)."""

    def __init__(self, label: str, show: bool):
        import time

        self.label, self.show, self.t0 = label, show, time.perf_counter()

    def __call__(self, done: int, total: int) -> None:
        if not self.show or total <= 0:
            return
        import time

        frac = min(1.0, done / total)
        el = time.perf_counter() - self.t0
        eta = el / frac - el if frac > 0 else 0.0
        bar = "#" * int(30 * frac)
        print(f"\r{self.label} [{bar:30s}] {100 * frac:3.0f} %  ETA {eta:4.0f} s", end="",
              file=sys.stderr, flush=True)

    def done(self) -> None:
        if self.show:
            print(file=sys.stderr)


def add_reflex_parser(sub, parser_class=argparse.ArgumentParser) -> None:
    """Add ``stumble reflex`` and its actions to the top-level subparsers ``sub``."""
    r = sub.add_parser("reflex", help="the reflex controllers: seed 003's network, Geyer & "
                       "Herr 2010",
                       description="The reflex controllers on the planar musculoskeletal "
                       "body: seed 003's neuromuscular network and Geyer & Herr 2010's "
                       "reflexes. Walk, fit, reproduce the shipped fits.")
    rsub = r.add_subparsers(dest="reflex_command", metavar="ACTION", parser_class=parser_class,
                            required=True)
    f = rsub.add_parser("fit", help="fit a reflex controller",
                        description="network (default): identify seed 003's network from "
                        "walking alone (inverse dynamics, static optimisation, "
                        "back-propagation), and with --closed-loop refine it in closed "
                        "loop (DAgger); writes network.npz, fit.json, "
                        "activity_fit.png, walking_moments.csv, walking_activity.csv "
                        "(and objective.png). "
                        "gh2010: optimise Geyer & Herr 2010's gains in closed loop "
                        "(CMA-ES) from the paper's; writes gh2010.json, fit.json, "
                        "history.jsonl and objective.png. Both write to DIR.")
    f.add_argument("--out", required=True, type=out_dir_arg, metavar="DIR",
                   help="output directory")
    f.add_argument("--controller", choices=("network", "gh2010"), default="network",
                   type=_reflex_controller,
                   help="which reflex controller to fit (default network; reflex, as "
                   "stumble trip names it, is the same)")
    f.add_argument("--seed", type=seed_arg, default=0,
                   help="initial weights or the evolution strategy's seed, 0 to 2^63 - 1 "
                   "(default 0)")
    f.add_argument("--generations", type=int, default=None, metavar="N",
                   help="gh2010: CMA-ES generations (default as shipped: 110 of 15 s walks "
                   "for --wiring gh2010, 100 of 10 s walks for seed003); network "
                   "--walk-es: 0 writes the start as given (with --ahead-from, the "
                   "responses combined), its objective evaluated once")
    from stumble.study.cli import workers_arg

    f.add_argument("--workers", type=workers_arg, default=None, metavar="N",
                   help="closed-loop fits: worker processes (default: one per core); the "
                   "result does not depend on it")
    f.add_argument("--iterations", type=int, default=None, metavar="N",
                   help="back-propagation iterations of the seed's schedule (default 1000)")
    f.add_argument("--refine", type=int, default=None, metavar="N",
                   help="quasi-Newton refinement iterations after it (default 1500; 0: "
                   "the seed's schedule only)")
    f.add_argument("--contact-afferents", action=argparse.BooleanOptionalAction,
                   default=None,
                   help="network: foot-contact afferents (the seed's proposed extension; "
                   "default: with them for --closed-loop, without otherwise)")
    f.add_argument("--muscles", choices=("seed", "hfl"), default=None,
                   help="network: seed 003's seven muscles per leg, or with the iliopsoas "
                   "(default: hfl for --closed-loop, seed otherwise)")
    loop = f.add_mutually_exclusive_group()
    loop.add_argument("--open-loop", action="store_true",
                      help="network: the seed's identification alone (the default; shipped "
                      "as --network open-loop)")
    loop.add_argument("--closed-loop", action="store_true",
                      help="network: then refine it in closed loop by DAgger with the "
                      "seed003-wired GH2010 expert (shipped as --network closed-loop)")
    loop.add_argument("--walk-es", default=None, metavar="NETWORK",
                      help="network: refine a shipped (closed-loop, placement, ...) or saved "
                      "network in closed loop by CMA-ES on a documented subset of its "
                      "weights (motor-neuron gains and biases, contact afferents, trunk "
                      "balance; fit_walk.network_space) on the walking objective, with "
                      "--knee-weight, --track-weight, --track-limit, --trunk-weight, "
                      "--starts, --delay-walks, "
                      "--pushes, "
                      "--timestep (default 0.002, the network's step), --generations "
                      "(default 150), "
                      "--sigma, --interneuron-biases, --touch-afferent, and trips by "
                      "--trip-set with --trip-start, --strategy-cost, --recovery-cost, "
                      "--touch-only (ours)")
    f.add_argument("--interneuron-biases", action="store_true",
                   help="network, --walk-es: the interneurons' biases join the subset")
    f.add_argument("--track-limit", type=float, default=None, metavar="DEG",
                   help="network, --walk-es: each joint's RMSE beyond DEG costs 20 a "
                   "degree (a walk held near the recording while trips are fitted; ours)")
    f.add_argument("--trunk-weight", type=float, default=None, metavar="W",
                   help="network, --walk-es: the walking objective's trunk term, weight W "
                   "(0-100): the RMSE of the trunk's lean from vertical against the "
                   "recorded stride's, as the tracking term weighs a joint's (ours; off "
                   "by default)")
    f.add_argument("--touch-afferent", action="store_true",
                   help="network, --walk-es: give the network a touch afferent first (the "
                   "foot touched by anything but the floor, into segments L4-S1; ours), "
                   "whose weights join the subset from 0")
    f.add_argument("--touch-response", action="store_true",
                   help="network, --walk-es: give the network a touch response first (the "
                   "stumbling corrective reaction: 65 ms after a foot's touch, excitations "
                   "of that leg's muscles for a time, then others, and of the other "
                   "leg's; ours), whose gains and durations join the subset from 0")
    f.add_argument("--cross-step", action="store_true",
                   help="network, --walk-es --touch-response: give the response a recovery "
                   "step first (the other leg's excitations for a time from the touched "
                   "foot's landing; ours), its gains fitted from 0")
    f.add_argument("--cross-only", action="store_true",
                   help="network, --walk-es --touch-only --cross-step: fit the recovery "
                   "step alone, the rest of the response as the start has it")
    f.add_argument("--trip-sample", type=int, default=None, metavar="K",
                   help="network --walk-es --trip-set: judge each generation on K of the "
                   "set's trips, drawn afresh each generation (seeded), and take the "
                   "search's mean at the end, judged on all of them (for the pool set)")
    f.add_argument("--ahead-from", default=None, metavar="FILE|NAME",
                   help="network, --walk-es --touch-response --scr-phase foot: start the "
                   "response for a touch of the foot ahead from this network's (the same "
                   "walk, its response by the foot's place), the foot behind's from the "
                   "start's")
    f.add_argument("--set-response", default=None, metavar="SET.MUSCLE=GAIN[,...]",
                   help="network, --walk-es --touch-response: set these gains of the touch "
                   "response by hand first (-1 to 1; e.g. contra_ahead.HFL=1: the other "
                   "leg's hip flexor after a touch of the foot ahead); with --generations "
                   "0, the result (ours)")
    f.add_argument("--sigma", type=float, default=None, metavar="S",
                   help="network, --walk-es: CMA-ES's first step in units of each "
                   "parameter's scale (default 0.3; smaller for a second stage)")
    f.add_argument("--passes", type=int, default=None, metavar="N",
                   help="network, --closed-loop: DAgger passes (default 8)")
    f.add_argument("--loss", choices=("squared", "cross-entropy"), default=None,
                   help="network, --closed-loop: DAgger's training loss (default squared, "
                   "as the shipped networks'; cross-entropy keeps a motor neuron that "
                   "is driven off learning)")
    f.add_argument("--trip-episodes", type=int, default=None, metavar="N",
                   help="network, --closed-loop: each DAgger pass also runs N episodes "
                   "tripped by the obstacle in the walk's own gait, at swing fractions "
                   "drawn from 0.05-0.75 (default 0; give an expert with a touch "
                   "response, e.g. --expert expert-touch)")
    f.add_argument("--expert", type=Path, default=None, metavar="FILE",
                   help="network, --closed-loop: the DAgger expert, a gh2010.json of "
                   "`reflex fit --controller gh2010 --wiring seed003` (default: the "
                   "shipped one)")
    f.add_argument("--trips", action="store_true",
                   help="gh2010: the trip stage: from the default's walking fit, "
                   "knee-walk (or --params FILE), its gains and the stumbling corrective "
                   "reflex's on a 10 s walk and four obstacle trips in its own gait (60 "
                   "generations)")
    f.add_argument("--params", type=Path, default=None, metavar="FILE",
                   help="gh2010: the gh2010.json to start from, or a shipped set by name: "
                   f"{GH2010_NAMES} (with --trips the trip stage starts there; without, "
                   "the walk is refitted from there, a touch's reflexes kept as they are)")
    f.add_argument("--trip-set", choices=("four", "wide", "dense", "pool"), default=None,
                   help="gh2010 --trips, or network --walk-es: the stage's obstacle "
                   "trips (for --walk-es none unless given): four (gh2010's default), "
                   "twelve across swing 0.1-0.75 and the three start speeds (wide), or "
                   "thirty, swing 0.05-0.75 at 1.1 and 1.3 m/s (dense), or 116 at "
                   "1.05-1.35 m/s, swing 0.05-0.75 in steps of 0.025 (pool: network, with "
                   "--trip-sample)")
    f.add_argument("--scr-phase", choices=("any", "foot"), default=None,
                   help="gh2010 --trips: the stumbling corrective reflex the same at every "
                   "phase (any), or reversing as the tripped foot is behind or ahead of "
                   "the other (foot); default: the starting fit's; network --walk-es "
                   "--touch-response: foot gives the response sets for a touch of the foot "
                   "ahead of the other")
    f.add_argument("--strategy-cost", type=_weight, default=None, metavar="W",
                   help="gh2010 --trips, network --walk-es --trip-set: each of the "
                   "stage's trips in a human window "
                   "(elevating at 0.05-0.25 of swing, lowering at 0.55-0.75) costs W more "
                   "when the strategy read from the motion is not the human one (default "
                   "0: recovery alone; fit_walk.W_STRATEGY, 10, is half a lost trip)")
    f.add_argument("--placement", action="store_true",
                   help="gh2010: fit the swing-leg placement too (our addition after Song & "
                   "Geyer 2015: the swing hip driven toward a leg angle set by the centre "
                   "of mass's place and speed; a walking law, not with --touch-only)")
    f.add_argument("--track-weight", type=_weight, default=None, metavar="W",
                   help="gh2010: the objective's tracking term's weight (default 1, every "
                   "shipped fit's)")
    f.add_argument("--knee-weight", type=_weight, default=None, metavar="W",
                   help="gh2010: the objective's knee term, per degree of the knees' mean "
                   "extension beyond straight (default 0; 5 in knee-walk's fit; ours: the "
                   "fitted walkers stand their stance knee on the model's +5° stop)")
    f.add_argument("--pushes", action="store_true",
                   help="gh2010, network --walk-es: every candidate also walks 10 s with "
                   "two backward pushes on the pelvis (200 N for 0.2 s at 3 and 6.5 s), "
                   "the part not walked costing as a fall: a gait that gets its speed back "
                   "(ours; not with --touch-only); --closed-loop: every DAgger episode "
                   "walks through those pushes, and each pass is judged through them too")
    f.add_argument("--starts", default=None, metavar="V[,V...]",
                   help="gh2010: every candidate also walks 10 s from the walk played back "
                   "at each of these speeds (m/s, 0.7-1.6), the part not walked costing "
                   "as a fall: a walker that takes over from other walks (ours; not with "
                   "--touch-only)")
    f.add_argument("--delay-walks", default=None, metavar="K[,K...]",
                   help="network, --walk-es: every candidate also walks 10 s from the "
                   "1.2 m/s recording with every delay x K (0.5-3), the part not walked "
                   "costing as a fall: a walk that holds other delays, for delay studies "
                   "(ours; not with --touch-only)")
    f.add_argument("--timestep", type=float, default=None, metavar="S",
                   help="gh2010: the physics step (s) of every walk and trip of the fit, "
                   "recorded with the result, whose runs then take it (default: the "
                   "--params set's, 0.001 for the paper's)")
    f.add_argument("--trip-start", choices=("own", "playback"), default=None,
                   help="network, --walk-es with --trip-set: the trips start in the "
                   "network's own gait (own, the default here: from the recording a "
                   "network taking over at the trip falls untripped) or from the "
                   "recording at the trip (playback, seed 003's CASE 1 and 2)")
    f.add_argument("--past-obstacle", action="store_true",
                   help="gh2010 --trips, network --walk-es --trip-set: a trip recovers "
                   "only with the body past the box at 3 s, as the trip summaries count "
                   "since 2026-12-07 (default: still walking 3 s after the trip, as the "
                   "shipped fits were made, so that their commands re-run bit for bit)")
    f.add_argument("--max-tilt", type=float, default=None, metavar="DEG",
                   help="network --walk-es --trip-set: a trip recovers only with the trunk "
                   "within DEG of vertical when the recovery foot lands (5-90; people "
                   "recover within about 23-26, the limit issue 11 sets the state "
                   "machines; ours, off by default)")
    f.add_argument("--recovery-cost", type=_weight, default=None, metavar="W",
                   help="gh2010 --trips, network --walk-es --trip-set: each of the "
                   "stage's trips not recovered costs W "
                   "more, on top of its time term (default 0: the time walked on alone, "
                   "which gives a trip walked on 2.9 s nearly a recovery's credit; a lost "
                   "trip's time term is 20)")
    f.add_argument("--crossing", action="store_true",
                   help="gh2010 --trips: fit the crossing step after a touch too (each "
                   "leg's next step after the foot's obstacle touch, launched when the "
                   "other foot lands, with extra hip flexor, HAMS, TA and GAS drive)")
    f.add_argument("--touch-only", action="store_true",
                   help="gh2010 --trips: fit only the reflexes a touch triggers (the "
                   "stumbling corrective reflex, and the crossing step with --crossing); "
                   "the walking gains stay the starting fit's, and so does its walk; "
                   "network --walk-es --trip-set: only the touch response's gains and "
                   "durations (with --touch-response) and the touch afferent's weights (the "
                   "afferent given first if the network has neither), the walk the start's")
    f.add_argument("--load-from", choices=("floor", "any"), default=None,
                   help="gh2010 --trips: a leg's load, which switches it to stance: the "
                   "floor's force on its foot (floor, the shipped fits') or the floor's "
                   "and the obstacle's (any: a foot at rest on the box carries the body); "
                   "default: the starting fit's")
    f.add_argument("--stride-time", action="store_true",
                   help="gh2010: the objective also keeps the mean stride within 1.0-1.3 s "
                   "(the played-back walk's at 1.0-1.3 m/s; ((distance)/0.05 s)^2)")
    f.add_argument("--stance-weight", type=_weight, default=None, metavar="W",
                   help="gh2010: the weight of the objective's stance-fraction term "
                   "(((distance from 0.57-0.68)/0.05)^2; default 1, the shipped fits'; "
                   "20 makes 0.06 outside the band cost as much as 1.4 lost trips)")
    f.add_argument("--foot-angle", type=_weight, nargs="?", const=1.0, default=0.0,
                   metavar="W",
                   help="gh2010: the objective also tracks each foot's angle to the floor "
                   "against the recorded stride's (as a joint: RMSE/10 deg + its excess "
                   "over 8 deg/2 deg, times W, default 1), so that the swing foot is as "
                   "flat as the recorded one when an obstacle meets it")
    f.add_argument("--ta-bound", choices=("wide", "paper"), default="wide",
                   help="gh2010: bounds of the TA length reflex (l_off_ta, g_ta): wide (the "
                   "default, as shipped: 0.3-1.5 l_opt, 0.2-5x the paper's gain) or paper "
                   "(0.6-0.8 l_opt, 0.5-1.5x the paper's gain)")
    f.add_argument("--wiring", choices=("gh2010", "seed003"), default="gh2010",
                   help="gh2010: the paper's laws and delays (default), or seed003: the "
                   "laws the network can express on its nerves (the network's expert)")
    f.add_argument("--no-video", action="store_true",
                   help="skip walking_step.png (the rendered walking step)")

    rw = rsub.add_parser("walk", help="walk under a reflex controller",
                         description="Walk under a reflex controller from the played-back "
                         "walk at right heel strike: writes motion.csv, motion.mot, "
                         "motion.bvh, muscles.sto, events.json, summary.json, "
                         "joint_angles.png and walk.mp4 to DIR.")
    rw.add_argument("--out", required=True, type=out_dir_arg, metavar="DIR",
                    help="output directory")
    rw.add_argument("--controller", choices=("network", "gh2010"), default="network",
                    type=_reflex_controller,
                    help="network: seed 003's reflex network (default; reflex, as stumble "
                    "trip names it, is the same); gh2010: Geyer & Herr 2010's reflexes")
    rw.add_argument("--network", type=Path, metavar="FILE",
                    help="network controller: a network.npz, or a shipped network: "
                    "past-support (the default: walks within 10 deg and recovers "
                    "trips of both strategies past the box), placement-both (the default "
                    "before 2026-12-07), closed-loop (refined by DAgger), "
                    "placement (refined from a "
                    "placing expert), placement-es (placement refined by CMA-ES), "
                    "placement-walk (within 10 deg at every joint), placement-touch "
                    "(placement-walk with a touch response), placement-foot (the "
                    "response by the foot's place), past-foot (the same fitted with a "
                    "recovery past the box; past-swing is it with the other leg swung "
                    "through after a touch of the foot ahead, past-support it with the "
                    "support leg's GLU on and the tripped leg's VAS off after a touch of "
                    "the foot behind) or "
                    "open-loop (seed 003's identification alone, which "
                    "falls after 0.8 s)")
    rw.add_argument("--params", type=Path, metavar="FILE",
                    help="gh2010 controller: a gh2010.json from `stumble reflex fit "
                    f"--controller gh2010`, or a shipped set by name: {GH2010_NAMES}")
    rw.add_argument("--duration", type=_positive("duration"), default=20.0, metavar="S",
                    help="seconds to walk at most (default 20)")
    rw.add_argument("--speed", type=float, default=None, metavar="V",
                    help="speed of the walk played back before (0.7-1.6 m/s; default the "
                    "subject's 1.10); the controller then walks at its own speed")
    rw.add_argument("--timestep", type=float, default=None, metavar="S",
                    help="physics step (s; default the controller's: 0.002 for the network, "
                    "for gh2010 the step its set was fitted at; the network also runs at "
                    "whole numbers of its 1 ms tick, gh2010 at steps that divide its set's)")
    rw.add_argument("--no-video", action="store_true", help="skip walk.mp4")

    rp = rsub.add_parser("reproduce", help="re-run the fits that made a shipped set",
                         description="Re-run, as one job, the chain of closed-loop fits "
                         "recorded in a shipped Geyer & Herr set or network (each stage's "
                         "command, each starting from the stage before's result), each "
                         "stage into DIR/<its name>/, and compare each result that is "
                         "shipped too with the shipped parameters. Writes "
                         "DIR/reproduce.json after every stage; a stopped job run again "
                         "keeps the stages already done.")
    rp.add_argument("name", metavar="NAME",
                    help="a shipped set (e.g. knee-2ms-dense-wide-s3, the Geyer & Herr "
                    "default: five fits from the paper's gains, about 16-32 min on 2 "
                    "workers) or network (e.g. past-support, the default: thirteen fits "
                    "from the paper's gains through its expert and DAgger, about "
                    "66-73 min on 2 workers: 66.5 on an Intel Xeon, 2026-12-07; 73.0 "
                    "on an AMD EPYC before that day's faster physics step)")
    rp.add_argument("--out", required=True, type=out_dir_arg, metavar="DIR",
                    help="output directory")
    rp.add_argument("--from", dest="start_after", metavar="NAME",
                    help="start from this shipped result of the chain: its own fits are "
                    "not run (e.g. --from placement-touch)")
    rp.add_argument("--plan", action="store_true",
                    help="print the stages it would run, in order, with their commands and "
                    "the minutes each took when fitted; run and write nothing")


def cmd_reflex_walk(args) -> int:
    """``stumble reflex walk``: walk under a reflex controller and write its files."""
    import math

    from stumble.outputs import prepare_dir, write_reflex_walk
    from stumble.pipeline import simulate_walk

    if args.network and args.controller != "network":
        raise InputError("--network is for --controller network")
    if args.params and args.controller != "gh2010":
        raise InputError("--params is for --controller gh2010")
    network = params = None
    if args.network:
        network = _network_arg(args.network)
    if args.params:
        from stumble.control.reflex.gh2010 import load_params

        params = load_params(args.params)
    out = prepare_dir(args.out)
    if args.timestep is not None and not (math.isfinite(args.timestep)
                                          and 0.0002 <= args.timestep <= 0.005):
        raise InputError(f"--timestep must be 0.0002-0.005 s, got {args.timestep}")
    result = simulate_walk(args.controller, args.duration, args.speed, params=params,
                           network=network, timestep_s=args.timestep)
    written = write_reflex_walk(out, result, not args.no_video, sys.stderr.isatty())
    s = result.summary
    rm = s["rmse_deg"]
    what = f"fell after {s['walked_s']:.2f} s" if s["fell"] else f"walked {s['walked_s']:.1f} s"
    errors = ("/".join(f"{rm[j]:.1f}" for j in ("hip_flexion", "knee_angle", "ankle_angle"))
              if rm else "n/a")
    print(f"{args.controller}: {what}, {s['strides']} strides at {s['speed_m_per_s']:.2f} m/s, "
          f"stance {s['stance_fraction']}, RMSE hip/knee/ankle {errors} deg; wrote "
          f"{', '.join(written)} to {out}")
    return 0


def cmd_reflex_fit_gh2010(args) -> int:
    """``stumble reflex fit --controller gh2010``: the closed-loop CMA-ES of its gains."""
    import math
    import os

    from stumble.control.reflex.fit_walk import (
        GH2010_STAGES,
        SEED003_STAGES,
        TRIP_SETS,
        TRIP_STAGES,
        W_KNEE,
        W_STANCE,
        W_TRACK,
        fit_gh2010,
    )
    from stumble.outputs import prepare_dir, write_gh2010_fit

    if args.trips and args.wiring != "gh2010" and args.params is None:
        raise InputError(f"--trips --wiring {args.wiring} starts from a {args.wiring}-wired "
                         "set: give it by --params (e.g. expert-placement)")
    if (args.expert is not None or args.closed_loop or args.passes is not None
            or args.loss is not None or args.trip_episodes is not None):
        raise InputError("--expert, --closed-loop, --passes, --loss and --trip-episodes are "
                         "for --controller network")
    for flag, given in (("--trip-set", args.trip_set),
                        ("--scr-phase", args.scr_phase),
                        ("--strategy-cost", args.strategy_cost),
                        ("--recovery-cost", args.recovery_cost),
                        ("--past-obstacle", args.past_obstacle or None),
                        ("--crossing", args.crossing or None),
                        ("--touch-only", args.touch_only or None),
                        ("--load-from", args.load_from)):
        if given is not None and not args.trips:
            raise InputError(f"{flag} is for --trips (the trip stage)")
    start = start_fit = start_from = None
    if args.params is not None:
        import json
        from dataclasses import replace

        from stumble.control.reflex.gh2010 import file_sha256, load_params, named_file

        start, rewired = load_params(args.params), None
        if start.wiring != args.wiring and args.trips:
            raise InputError(f"--params {args.params} is wired {start.wiring}: the trip "
                             f"stage starts from a {args.wiring}-wired set")
        if start.wiring != args.wiring:  # the same gains on the other wiring's paths
            _notes([f"--params {args.params} is wired {start.wiring}: its gains start a "
                    f"{args.wiring}-wired walking fit"])
            rewired = start.wiring
            start = replace(start, wiring=args.wiring)
        src = named_file(args.params) or args.params
        start_fit = json.loads(src.read_text()).get("fit")
        start_from = {"params": str(args.params), "sha256": file_sha256(args.params)}
        if rewired is not None:  # recorded with the fit: the command rewires it again
            start_from["rewired_from"] = rewired
    stages = (TRIP_STAGES if args.trips else GH2010_STAGES if args.wiring == "gh2010"
              else SEED003_STAGES)
    if args.trip_set == "pool":
        raise InputError("--trip-set pool (116 trips, to sample from) is for --controller "
                         "network --walk-es --trip-sample")
    if args.trip_set is not None:
        stages = tuple((g, w, TRIP_SETS[args.trip_set]) for g, w, _t in stages)
    if args.generations is not None:  # the same stages, shortened (a quick look)
        if args.generations < 1:
            raise InputError(f"--generations must be at least 1, got {args.generations}")
        stages = tuple((max(1, round(args.generations * g / sum(x[0] for x in stages))), w, t)
                       for g, w, t in stages)
    # the weights and costs are finite and within 0-MAX_WEIGHT (_weight, their type)
    strategy_cost = args.strategy_cost or 0.0
    track_weight = W_TRACK if args.track_weight is None else args.track_weight
    knee_weight = W_KNEE if args.knee_weight is None else args.knee_weight
    if knee_weight and args.touch_only:
        raise InputError("--knee-weight weighs the walk: it refits the walk, so not with "
                         "--touch-only")
    stance_weight = W_STANCE if args.stance_weight is None else args.stance_weight
    if args.placement and args.touch_only:
        raise InputError("--placement is a walking law: it refits the walk, so not with "
                         "--touch-only")
    starts = _start_speeds(args.starts)
    if starts and args.touch_only:
        raise InputError("--starts tests the walk: it refits the walk, so not with "
                         "--touch-only")
    if args.pushes and args.touch_only:
        raise InputError("--pushes tests the walk: it refits the walk, so not with "
                         "--touch-only")
    recovery_cost = args.recovery_cost or 0.0
    if args.timestep is not None and not (math.isfinite(args.timestep)
                                          and 0.0002 <= args.timestep <= 0.005):
        raise InputError(f"--timestep must be 0.0002-0.005 s, got {args.timestep}")
    gens = sum(g for g, _w, _t in stages)
    workers = args.workers or os.cpu_count() or 1  # --workers is at least 1 (workers_arg)
    out = prepare_dir(args.out)
    bar = _Progress("fitting gh2010", sys.stderr.isatty())
    res = fit_gh2010(seed=args.seed, stages=stages, workers=workers, out=out,
                     progress=lambda row: bar(row["generation"] + 1, gens),
                     wiring=args.wiring, trips=args.trips, start=start,
                     start_fit=start_fit, start_from=start_from,
                     scr_phase=args.scr_phase,
                     ta_bound=args.ta_bound, strategy_cost=strategy_cost,
                     crossing=args.crossing, foot_angle=args.foot_angle,
                     load_from=args.load_from, stride_time=args.stride_time,
                     stance_weight=stance_weight, touch_only=args.touch_only,
                     recovery_cost=recovery_cost, placement=args.placement,
                     pushes=args.pushes, track_weight=track_weight, starts=starts,
                     knee_weight=knee_weight, timestep_s=args.timestep,
                     past_obstacle=args.past_obstacle)
    bar.done()
    written, walk = write_gh2010_fit(out, res)
    s = walk.summary
    print(f"gh2010 fitted: objective {res.best_cost:.3f} after {res.evaluations} walks in "
          f"{res.wall_time_s:.0f} s; a 20 s walk: {s['walked_s']:.1f} s walked at "
          f"{s['speed_m_per_s']:.2f} m/s; wrote {', '.join(written)} to {out}")
    return 0


def cmd_reflex_fit_network_es(args) -> int:
    """``stumble reflex fit --controller network --walk-es NETWORK``: CMA-ES on a documented
    subset of a network's weights (``fit_walk.fit_network_es``)."""
    import math
    import os

    from stumble.control.reflex.fit_walk import (
        NETWORK_ES_GENERATIONS,
        W_KNEE,
        W_TRACK,
        fit_network_es,
    )
    from stumble.jsonio import write_json
    from stumble.outputs import prepare_dir
    from stumble.pipeline import simulate_walk
    from stumble.viz.reflex_plots import plot_objective

    for flag, given in (("--trips", args.trips or None), ("--params", args.params),
                        ("--crossing", args.crossing or None),
                        ("--load-from", args.load_from), ("--placement", args.placement or None),
                        ("--expert", args.expert),
                        ("--passes", args.passes), ("--loss", args.loss),
                        ("--trip-episodes", args.trip_episodes),
                        ("--foot-angle", args.foot_angle or None),
                        ("--stride-time", args.stride_time or None),
                        ("--stance-weight", args.stance_weight),
                        ("--iterations", args.iterations), ("--refine", args.refine),
                        ("--muscles", args.muscles),
                        ("--contact-afferents", args.contact_afferents)):
        if given is not None:
            raise InputError(f"{flag} is not for --walk-es")
    start, start_from = _network_record(args.walk_es)
    ahead_from = None
    if args.ahead_from is not None:
        if args.scr_phase != "foot":
            raise InputError("--ahead-from is for --touch-response --scr-phase foot")
        ahead_from = _network_record(args.ahead_from)
        start.with_touch_response(by_foot=True).with_ahead_response(ahead_from[0])  # checked
    set_response = None
    if args.set_response is not None:
        from stumble.control.reflex.fit_walk import parse_set_response

        set_response = parse_set_response(args.set_response)
        check = start.with_touch_response(by_foot=args.scr_phase == "foot")
        if ahead_from is not None:  # in fit_network_es's order
            check = check.with_ahead_response(ahead_from[0])
        if args.cross_step:
            check = check.with_cross_step()
        check.with_response_gains(set_response)  # checked
    knee = W_KNEE if args.knee_weight is None else args.knee_weight  # within 0-MAX_WEIGHT
    track = W_TRACK if args.track_weight is None else args.track_weight
    gens = NETWORK_ES_GENERATIONS if args.generations is None else args.generations
    if gens < 0:
        raise InputError(f"--generations must be at least 0, got {gens}")
    if args.timestep is not None:
        from stumble.control.reflex.network import tick_ratio

        if not (math.isfinite(args.timestep) and 0.0002 <= args.timestep <= 0.005):
            raise InputError(f"--timestep must be 0.0002-0.005 s, got {args.timestep}")
        tick_ratio(args.timestep, start.topology.rate_hz)
    starts = _start_speeds(args.starts)
    delay_walks = _delay_scales(args.delay_walks)
    workers = args.workers or os.cpu_count() or 1  # --workers is at least 1 (workers_arg)
    from stumble.control.reflex.fit_walk import NETWORK_ES_SIGMA, TRIP_SETS

    trips = TRIP_SETS[args.trip_set] if args.trip_set else ()
    if args.trip_sample is not None and not (trips and 1 <= args.trip_sample <= len(trips)):
        raise InputError(f"--trip-sample must be 1-{len(trips)} (the --trip-set's trips), "
                         f"got {args.trip_sample}" if trips else
                         "--trip-sample needs --trip-set")
    if args.scr_phase is not None and not args.touch_response:
        raise InputError("--scr-phase (network --walk-es) is for --touch-response")
    if args.touch_only:
        if not trips:
            raise InputError("--touch-only (network): the touch stage needs --trip-set")
        for flag, given in (("--starts", args.starts), ("--delay-walks", args.delay_walks),
                            ("--pushes", args.pushes or None),
                            ("--interneuron-biases",
                                                          args.interneuron_biases or None),
                            ("--track-limit", args.track_limit),
                            ("--trunk-weight", args.trunk_weight)):
            if given is not None:
                raise InputError(f"{flag} weighs the walk: not with --touch-only (the "
                                 "touch stage keeps the start's walk)")
    costs = {}
    for flag, v in (("--strategy-cost", args.strategy_cost),
                    ("--recovery-cost", args.recovery_cost),
                    ("--trip-start", args.trip_start),
                    ("--past-obstacle", args.past_obstacle or None),
                    ("--max-tilt", args.max_tilt)):
        if v is not None and not trips:
            raise InputError(f"{flag} needs --trip-set")
    if args.max_tilt is not None and not (math.isfinite(args.max_tilt)
                                          and 5.0 <= args.max_tilt <= 90.0):
        raise InputError(f"--max-tilt must be 5-90 degrees, got {args.max_tilt}")
    if args.max_tilt is not None and not args.recovery_cost:
        raise InputError("--max-tilt needs --recovery-cost W > 0: a recovery past the "
                         "limit costs as one not recovered")
    if args.track_limit is not None and not (math.isfinite(args.track_limit)
                                             and args.track_limit > 0):
        raise InputError(f"--track-limit must be a number of degrees > 0, got "
                         f"{args.track_limit}")
    if args.trunk_weight is not None and not (math.isfinite(args.trunk_weight)
                                              and 0 <= args.trunk_weight <= 100):
        raise InputError(f"--trunk-weight must be a number in 0-100, got {args.trunk_weight}")
    for key, v in (("strategy_cost", args.strategy_cost),
                   ("recovery_cost", args.recovery_cost)):
        costs[key] = 0.0 if v is None else v  # within 0-MAX_WEIGHT (_weight)

    sigma = NETWORK_ES_SIGMA if args.sigma is None else args.sigma
    if not (math.isfinite(sigma) and 0.0 < sigma <= 5.0):
        raise InputError(f"--sigma must be a number in (0, 5], got {args.sigma}")
    out = prepare_dir(args.out)
    bar = _Progress("fitting the network", sys.stderr.isatty())
    net, res = fit_network_es(start, start_from, seed=args.seed, generations=gens,
                              workers=workers, out=out,
                              progress=lambda row: bar(row["generation"] + 1, max(gens, 1)),
                              knee_weight=knee, track_weight=track, starts=starts,
                              timestep_s=args.timestep,
                              interneuron_biases=args.interneuron_biases, sigma=sigma,
                              trips=trips,
                              trip_start=(args.trip_start or "own") if trips else None,
                              touch=args.touch_afferent, touch_only=args.touch_only,
                              touch_response=args.touch_response,
                              response_by_foot=args.scr_phase == "foot",
                              ahead_from=ahead_from, trip_sample=args.trip_sample,
                              cross_step=args.cross_step, cross_only=args.cross_only,
                              track_limit_deg=args.track_limit, delay_walks=delay_walks,
                              pushes=args.pushes, trunk_weight=args.trunk_weight or 0.0,
                              past_obstacle=args.past_obstacle,
                              set_response=set_response, max_tilt_deg=args.max_tilt,
                              **costs)
    bar.done()
    walk = simulate_walk("network", 20.0, network=net)
    report = dict(net.info["fit"])
    report["walk_20s"] = {k: v for k, v in walk.summary.items() if k != "events"}
    write_json(out / "fit.json", report)
    plot_objective(out / "objective.png", res.history,
                   f"Network closed-loop CMA-ES (seed {args.seed}): objective "
                   f"{res.best_cost:.3f} after {res.evaluations} walks")
    s = walk.summary
    rm = s["rmse_deg"] or {}
    errors = "/".join(f"{rm[j]:.1f}" for j in ("hip_flexion", "knee_angle", "ankle_angle")
                      if j in rm) or "n/a"
    print(f"network {'fitted' if gens else 'written as given (no search)'}: objective "
          f"{res.best_cost:.3f} after {res.evaluations} walks in "
          f"{res.wall_time_s:.0f} s; a 20 s walk: {s['walked_s']:.1f} s walked at "
          f"{s['speed_m_per_s']:.2f} m/s, RMSE hip/knee/ankle {errors} deg; wrote "
          f"network.npz, history.jsonl, best.json, fit.json, objective.png to {out}")
    return 0


def cmd_reflex_reproduce(args) -> int:
    """``stumble reflex reproduce``: the recorded chain of fits of a shipped set, re-run."""
    from stumble.control.reflex.reproduce import jobs, run
    from stumble.outputs import prepare_dir

    if args.out.exists() and not args.out.is_dir():  # --plan too: it names DIR's stages
        raise InputError(f"--out {args.out}: exists and is not a directory")
    if args.plan:  # what would run, in order, with the minutes each took when fitted
        import shlex

        _kind, todo = jobs(args.name, args.out, args.start_after)
        for i, st in enumerate(todo, 1):
            print(f"stage {i} of {len(todo)} ({st.tag}; {st.minutes:.1f} min as recorded): "
                  f"stumble {shlex.join(st.argv)}")
        print(f"{args.name}: {len(todo)} stage(s), {sum(s.minutes for s in todo):.1f} min as "
              "recorded when each was fitted (docs/reflex.md gives the times re-run on this "
              "project's machines); nothing run or written")
        return 0
    jobs(args.name, args.out, args.start_after)  # a bad name before the directory is made
    prepare_dir(args.out)  # and writable: one line, before the first stage
    rep = run(args.name, args.out, start_after=args.start_after)
    same = rep["same_as_shipped"]
    print(f"{args.name}: {len(rep['stages'])} stage(s) in {rep['minutes']:.1f} min; "
          + ("the shipped parameters, bit for bit" if same else
             "differs from the shipped file (see reproduce.json)" if same is False else
             "not compared") + f"; wrote {rep['result']} and {args.out / 'reproduce.json'}")
    return 0


def cmd_reflex(args) -> int:
    """``stumble reflex ACTION``: ``walk`` and ``reproduce`` by their own commands; ``fit``
    here, its options checked, then the fit they name (Geyer & Herr's CMA-ES, the
    network's CMA-ES, or the network's identification and DAgger) run and its files
    written."""
    if args.reflex_command == "walk":
        return cmd_reflex_walk(args)
    if args.reflex_command == "reproduce":
        return cmd_reflex_reproduce(args)
    if args.trip_start is not None and args.walk_es is None:
        raise InputError("--trip-start is for --walk-es (with --trip-set)")
    if args.cross_step and (args.walk_es is None or args.controller == "gh2010"
                            or not args.touch_response):
        raise InputError("--cross-step is for --controller network --walk-es "
                         "--touch-response")
    if args.cross_only and not (args.cross_step and args.touch_only):
        raise InputError("--cross-only is for --touch-only --cross-step")
    if args.trip_sample is not None and (args.walk_es is None
                                         or args.controller == "gh2010"):
        raise InputError("--trip-sample is for --controller network --walk-es --trip-set")
    if args.delay_walks is not None and (args.walk_es is None or args.controller == "gh2010"):
        raise InputError("--delay-walks is for --controller network --walk-es")
    if args.ahead_from is not None and (args.walk_es is None or args.controller == "gh2010"):
        raise InputError("--ahead-from is for --controller network --walk-es "
                         "--touch-response --scr-phase foot")
    if args.max_tilt is not None and (args.walk_es is None or args.controller == "gh2010"):
        raise InputError("--max-tilt is for --controller network --walk-es --trip-set")
    if args.set_response is not None and (args.walk_es is None or args.controller == "gh2010"
                                          or not args.touch_response):
        raise InputError("--set-response is for --controller network --walk-es "
                         "--touch-response")
    if args.controller == "gh2010":
        if (args.walk_es is not None or args.interneuron_biases or args.sigma is not None
                or args.touch_afferent or args.track_limit is not None
                or args.touch_response or args.trunk_weight is not None):
            raise InputError("--walk-es, --interneuron-biases, --sigma, --touch-afferent, "
                             "--touch-response, --trunk-weight and "
                             "--track-limit are for --controller network")
        return cmd_reflex_fit_gh2010(args)
    if args.walk_es is not None:
        return cmd_reflex_fit_network_es(args)
    if (args.interneuron_biases or args.sigma is not None or args.touch_afferent
            or args.track_limit is not None or args.touch_response
            or args.trunk_weight is not None):
        raise InputError("--interneuron-biases, --sigma, --touch-afferent, --touch-response, "
                         "--trunk-weight and --track-limit are for --walk-es")
    if (args.trips or args.params is not None or args.trip_set or args.scr_phase
            or args.ta_bound != "wide" or args.strategy_cost is not None or args.crossing
            or args.recovery_cost is not None or args.placement or args.past_obstacle
            or (args.pushes and not args.closed_loop) or args.starts is not None
            or args.timestep is not None
            or args.foot_angle or args.load_from is not None or args.stride_time
            or args.stance_weight is not None or args.touch_only
            or args.track_weight is not None or args.knee_weight is not None):
        raise InputError("--trips, --params, --trip-set, --scr-phase, --strategy-cost, "
                         "--recovery-cost, --past-obstacle, --crossing, --touch-only, "
                         "--load-from, "
                         "--foot-angle, --stride-time, --stance-weight, --track-weight, "
                         "--knee-weight, --placement, --pushes, --starts, --timestep and "
                         "--ta-bound are for --controller gh2010 (some also for network "
                         "--walk-es; --pushes also for --closed-loop)")
    if args.generations is not None:
        raise InputError("--generations is for --controller gh2010 and --walk-es (the "
                         "CMA-ES fits); the identification and --closed-loop (DAgger) take "
                         "--iterations, --refine and --passes")
    from stumble.control.reflex.identify import ITERATIONS, REFINE_ITERATIONS, fit
    from stumble.outputs import prepare_dir, write_fit

    it = ITERATIONS if args.iterations is None else args.iterations
    refine = REFINE_ITERATIONS if args.refine is None else args.refine
    if it < 0 or refine < 0 or it + refine == 0:
        raise InputError("--iterations and --refine must be >= 0 and not both 0")
    closed = args.closed_loop
    muscles = args.muscles or ("hfl" if closed else "seed")
    contact = closed if args.contact_afferents is None else args.contact_afferents
    passes = args.passes
    expert = expert_text = None
    if args.expert is not None:
        from stumble.control.reflex.gh2010 import file_sha256, load_params

        if not closed:
            raise InputError("--expert is for --closed-loop (the DAgger expert)")
        expert = load_params(args.expert)
        if expert.wiring != "seed003":
            raise InputError(f"--expert {args.expert} is wired {expert.wiring}: the network "
                             "learns from a seed003-wired expert (`reflex fit --controller "
                             "gh2010 --wiring seed003`); on Geyer & Herr's own delays its "
                             "DAgger passes fell within 0.9-5.3 s (docs/reflex-fits.md)")
        expert_text = f"{args.expert} (sha256 {file_sha256(args.expert)})"
    if passes is not None and (not closed or passes < 1):
        raise InputError("--passes is for the closed-loop fit and must be at least 1")
    if args.loss is not None and not closed:
        raise InputError("--loss is for --closed-loop (DAgger's training loss)")
    trips = args.trip_episodes
    if trips is not None and not closed:
        raise InputError("--trip-episodes is for --closed-loop (DAgger's trip episodes)")
    if trips is not None and not 0 <= trips <= 20:
        raise InputError(f"--trip-episodes {trips}: must be 0-20 (trip episodes per DAgger "
                         "pass)")
    out = prepare_dir(args.out)
    bar = _Progress("identifying", sys.stderr.isatty())
    result = fit(seed=args.seed, iterations=it, refine_iterations=refine,
                 contact=contact, progress=bar, muscle_set=muscles)
    bar.done()
    r = result.report
    identified = (f"identified: average activity error {100 * r['avg_error']:.2f} %, maximum "
                  f"{100 * r['max_error']:.1f} % (seed 003: 2.0 %, 36 %) after "
                  f"{r['iterations']} iterations in {r['wall_time_s']:.1f} s")
    closed_loop = None
    if closed:
        import os

        from stumble.control.reflex.dagger import PASSES, dagger
        from stumble.control.reflex.fit_walk import PUSHES
        from stumble.control.reflex.gh2010 import shipped_params

        n = passes or PASSES
        bar = _Progress("closed loop", sys.stderr.isatty())
        closed_loop = dagger(result.network, result.ident,
                             expert or shipped_params("seed003"), n, expert=expert_text,
                             out_dir=out,
                             seed=args.seed, workers=args.workers or os.cpu_count() or 1,
                             progress=lambda row: bar(row["pass"] + 1, n),
                             pushes=PUSHES if args.pushes else (),
                             loss=args.loss or "squared", trips=trips or 0)
        bar.done()
    written = write_fit(out, result, video=not args.no_video, closed_loop=closed_loop)
    print(identified + ("" if closed_loop else f"; wrote {', '.join(written)} to {out}"))
    if closed_loop is None:
        return 0
    best = min(closed_loop.history, key=lambda h: h["cost"]) if closed_loop.history else None
    what = (f"best pass walks {best['walked_s']:.1f} of 10 s" if best else "no pass")
    print(f"closed loop: {len(closed_loop.history)} passes in {closed_loop.wall_time_s:.0f} s, "
          f"{what}; wrote {', '.join(written)} to {out}")
    return 0
