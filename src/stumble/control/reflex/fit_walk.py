"""Closed-loop fitting of reflex controllers: an evolution strategy on one walking objective.

Every closed-loop fit of this package (the GH2010 reflexes, the refinement of the seed's
network) minimises the same objective of a simulated walk from the played-back state
at right heel strike (``stumble.pipeline.simulate_walk``):

    J = W_FALL · (1 − min(walked / duration,
                          distance / (1.0 m/s · duration)))        time (and way) walked
      + W_TRACK · (RMS over joints of the RMSE / 10°
                   + Σ_joints max(0, RMSE − 8°) / 2°)             tracking of the
                                                                  recorded stride
      + W_EFFORT · mean activation²                             effort (F_max-weighted)
      + W_SPEED · (distance of the speed from 1.0–1.3 m/s / 0.1 m/s)²
      + w_stance · (distance of the stance fraction from 0.57–0.68 / 0.05)²
                                                  (w_stance ``W_STANCE``, 1, unless asked)
     [+ w_foot · (RMSE of the feet's angle to the floor / 10°
                  + max(0, that RMSE − 8°) / 2°)]       with ``foot_angle`` w_foot > 0
     [+ W_STRIDE · (distance of the mean stride time from 1.0–1.3 s / 0.05 s)²]
                                                                  with ``stride_time``
     [+ w_trunk · (RMSE of the trunk's lean / 10° + max(0, that RMSE − 8°) / 2°)]
                                                   with ``trunk_weight`` w_trunk > 0

so that a walker first learns not to fall (nor to stand still: the first term counts
the way covered at 1 m/s at least), then to walk like the recording (every joint
within 8°, the hinge terms), with the least effort, at a human speed and stance
fraction (bands inside the walking criteria of docs/reflex.md, 0.9–1.4 m/s and 0.55–0.70, so
that a fitted walker meets them with a margin). The foot term (``foot_angle``, off in
the shipped fits' objective) tracks each foot's angle in the sagittal plane
(``analysis.foot_angles``) against the recorded stride's: joint angles within 8° can
hold the swing foot 15–30° toe up where the recorded foot is about flat (at 0.6–0.75 of
swing, from 14° toe down to 6° toe up), so that an obstacle ahead of the toe meets the
heel, and the foot comes to rest on the box's edge instead of being lowered behind it
(docs/reflex-fits.md). The trunk term (``trunk_weight``, off in the shipped fits' objective) tracks
the torso's lean from vertical (``analysis.trunk_lean``) against the recorded stride's:
the hip, knee and ankle angles are relative to the pelvis and the segment above them,
so a walker can track them within 10° with its trunk 10° further forward than the
recording's (the default network: 24° on average, up to 32°, against the recording's
12–16°). The strategy is CMA-ES (Hansen 2016; the ``cmaes`` package), seeded, so a
fit is reproduced exactly from its seed; candidates of one generation are evaluated in
parallel worker processes and told back in order, so the worker count does not change
the result. Each generation's figures are appended to ``history.jsonl`` and the best
candidate so far to ``best.json`` as the fit runs.
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stumble.errors import InputError

# the physics step (s) of the network's closed-loop fits and DAgger's judging (every
# shipped network was refined at it; runs default to 2 ms, ``trip.DEFAULT_TIMESTEP_S``);
# GH2010 fits take their set's (``GH2010Params.timestep_s``, ``--timestep``)
FIT_TIMESTEP_S = 0.001
W_FALL = 100.0
W_TRACK = 1.0
W_EFFORT = 1.0
W_SPEED = 1.0
W_STANCE = 1.0
W_FOOT = 1.0  # the foot-angle term's weight by default (``--foot-angle``; a joint's)
# the stride-time term (``stride_time``, ``--stride-time``; off in the shipped fits): the
# played-back walk's strides at 1.0-1.3 m/s last 1.30-1.07 s (subject01, scaled with
# speed); trip stages without it grew the strides to 1.5-1.6 s (docs/reflex-fits.md)
W_STRIDE = 1.0
# the knee term (``knee_weight``, ``--knee-weight``; 0, off, but in ``knee-walk``, the
# default's walk, fitted with 5): per
# degree of the knees' mean extension beyond straight (``knee_hyperextension_deg``). Our
# addition: every fitted walker stands its stance knee on the model's +5° stop, where
# people flex it about 20° after heel strike (the knee's 15.5° RMSE); a stop carries the
# body for no muscle effort, so the effort term pays for it. SCONE's gait objectives
# penalise such joint-limit loads likewise.
W_KNEE = 0.0
# ``--pushes`` (ours; off unless asked; the pushed sets, ``pushed-walk`` and ``pushed``
# on it, and the default's walk, ``knee-walk``, were fitted with it): each candidate
# also walks PUSH_WALK_S from the same start with two backward pushes on the pelvis,
# PUSHES ((start s, duration s, force N), + forward: 40 N·s each, about −0.57 m/s for 70
# kg, a trip's speed loss in part: a trip slows our walker from 1.05 to 0.1 m/s within
# 0.45 s), and that walk's part not walked costs as a fall does (``W_FALL``): a gait
# that gets its speed back, after Song & Geyer 2015, whose walker was optimised on rough
# ground
PUSH_WALK_S = 10.0
PUSHES = ((3.0, 0.2, -200.0), (6.5, 0.2, -200.0))
# ``--starts V,...`` (ours; none unless asked): each candidate also walks PUSH_WALK_S from
# the walk played back at each of these speeds (m/s), the part not walked costing as a
# fall (``push_term``): a walker that takes over from slower and faster walks, as the
# network's expert must (DAgger's episodes start from 1.0-1.3 m/s walks)
# ``--delay-walks K,...`` (ours; none unless asked): each candidate also walks PUSH_WALK_S
# from the same start with every delay × K (``Network.with_delay_scale``, the trunk
# balance's too), the part not walked costing as a fall (``push_term``): a walker whose
# gait does not hang on its delays being exactly the ones it was fitted at, so that a
# study over delay scales asks how delays change trips and not whether the walk survives
# them (the shipped networks before it fall within 2 s at delays × 1.05)
STRIDE_BAND = (1.0, 1.3)  # s
SPEED_BAND = (1.0, 1.3)  # m/s
STANCE_BAND = (0.57, 0.68)
TRACK_HINGE_DEG = 8.0
# ``--track-limit DEG`` (ours; none unless asked): each joint's RMSE beyond DEG costs
# W_TRACK_LIMIT per degree: a walk held near the recording as a near-constraint while
# trips are fitted (a recovered trip is worth about 25, so 20 a degree outweighs it)
W_TRACK_LIMIT = 20.0


def _outside(v: float, band: tuple[float, float]) -> float:
    return max(band[0] - v, 0.0, v - band[1])


def walk_cost(summary: dict, effort: float, foot_angle: float = 0.0,
              stride_time: bool = False,
              stance_weight: float = W_STANCE,
              track_weight: float = W_TRACK,
              knee_weight: float = W_KNEE,
              track_limit_deg: float | None = None,
              trunk_weight: float = 0.0) -> tuple[float, dict]:
    """The objective J of a walk's summary (``walk_metrics``) and its mean
    F_max-weighted squared activation; returns J and its terms; ``foot_angle``: the
    foot-angle term's weight (0: none; ``W_FOOT``, 1, a joint's; on the summary's
    ``foot_angle_rmse_deg``); ``stride_time``: with the stride-time term (``W_STRIDE``,
    ``STRIDE_BAND``; the summary's ``stride_s``); ``stance_weight``: the stance term's
    weight (``W_STANCE``, 1, in every shipped fit); ``track_weight``: the tracking term's
    (``W_TRACK``, 1, in every shipped fit); ``knee_weight``: the knee term's, per degree
    of ``knee_hyperextension_deg`` (``W_KNEE``, 0: none; 5 in ``knee-walk``'s fit);
    ``track_limit_deg``: each joint's RMSE beyond it costs ``W_TRACK_LIMIT`` a degree
    (None: no such term); ``trunk_weight``: the trunk term's weight (0: none; on the
    summary's ``trunk_rmse_deg``)."""
    T = summary["duration_s"]
    walked = min(summary["walked_s"] / T,
                 max(summary.get("distance_m", T * SPEED_BAND[0]), 0.0) / (SPEED_BAND[0] * T))
    rmse = np.array(list(summary["rmse_deg"].values()))
    track = (float(np.sqrt((rmse ** 2).mean())) / 10.0
             + float(np.maximum(rmse - TRACK_HINGE_DEG, 0.0).sum()) / 2.0) if rmse.size else 10.0
    speed = _outside(summary["speed_m_per_s"], SPEED_BAND) / 0.1
    sf = summary["stance_fraction"]
    stance = 2.0 if sf is None else _outside(sf, STANCE_BAND) / 0.05
    terms = {"fall": W_FALL * (1.0 - walked), "track": float(track_weight) * track,
             "effort": W_EFFORT * effort, "speed": W_SPEED * speed ** 2,
             "stance": float(stance_weight) * stance ** 2}
    if foot_angle:
        f = summary.get("foot_angle_rmse_deg")
        terms["foot"] = float(foot_angle) * (10.0 if f is None else
                                  f / 10.0 + max(f - TRACK_HINGE_DEG, 0.0) / 2.0)
    if knee_weight:
        terms["knee"] = float(knee_weight) * summary.get("knee_hyperextension_deg", 0.0)
    if track_limit_deg is not None:
        terms["track_limit"] = W_TRACK_LIMIT * (
            float(np.maximum(rmse - track_limit_deg, 0.0).sum()) if rmse.size else 10.0)
    if trunk_weight:
        r = summary.get("trunk_rmse_deg")
        terms["trunk"] = float(trunk_weight) * (10.0 if r is None else
                                                r / 10.0 + max(r - TRACK_HINGE_DEG, 0.0) / 2.0)
    if stride_time:
        st = summary.get("stride_s")
        terms["stride"] = W_STRIDE * (4.0 if st is None else
                                      (_outside(st, STRIDE_BAND) / 0.05) ** 2)
    if summary.get("diverged"):
        terms["fall"] = W_FALL
    return float(sum(terms.values())), terms


def push_term(summary: dict | None) -> float:
    """``W_FALL`` times the part of the pushed walk (``PUSHES``) not walked, by time or by
    way (as ``walk_cost``'s fall term); the whole of it without a summary (a walker that
    fell unpushed)."""
    if summary is None:
        return W_FALL
    done = min(summary["walked_s"] / PUSH_WALK_S,
               summary["distance_m"] / (1.0 * PUSH_WALK_S))
    return W_FALL * (1.0 - min(1.0, max(0.0, done)))


def effort_of(result) -> float:
    """Mean over time of the F_max-weighted mean squared muscle activation."""
    rec, body = result.recording, result.body
    m = body.model
    ids = [m.actuator(g.name).id for g in body.muscles]
    act = rec.activation[:, m.actuator_actadr[ids]]
    f = np.array([g.f_max_n for g in body.muscles])
    return float(((act ** 2) @ f).mean() / f.sum()) if len(act) else 1.0


@dataclass(frozen=True)
class Space:
    """How a candidate vector x maps to parameters: θ = clip(θ0 + x·scale, lo, hi)."""

    names: tuple[str, ...]
    start: np.ndarray
    scale: np.ndarray
    lo: np.ndarray
    hi: np.ndarray

    def to_params(self, x: np.ndarray) -> np.ndarray:
        """Parameters of a candidate."""
        return np.clip(self.start + np.asarray(x) * self.scale, self.lo, self.hi)

    def to_x(self, theta: np.ndarray) -> np.ndarray:
        """The candidate of given parameters."""
        return (np.asarray(theta) - self.start) / self.scale


@dataclass
class FitResult:
    """A closed-loop fit: the best parameters and the run's history."""

    best_theta: np.ndarray
    best_cost: float
    best_terms: dict
    history: list[dict] = field(default_factory=list)
    evaluations: int = 0
    wall_time_s: float = 0.0
    space: Space | None = None


def cma_fit(evaluate: Callable[[np.ndarray], tuple[float, dict]], space: Space,
            seed: int = 0, generations: int = 100, popsize: int | None = None,
            sigma: float = 0.5, workers: int = 1, out: Path | None = None,
            progress: Callable[[dict], None] | None = None, initializer=None,
            initargs: tuple = (), target: float | None = None, first_generation: int = 0,
            stage: str = "", fixed: dict | None = None, sample=None,
            split=None) -> FitResult:
    """Minimise ``evaluate(theta)`` (a picklable, top-level function returning (J, terms))
    over ``space`` with seeded CMA-ES, ``workers`` processes evaluating each generation.
    Stops after ``generations`` or once the best J is below ``target``; ``generations``
    0 evaluates the start alone (one row, the start "best"). Generations are
    numbered from ``first_generation`` and the history is appended to ``out`` when it
    does not start at 0 (a later stage of one fit). ``fixed``: the parameters outside the
    space, written with the best candidate's to ``best.json`` so that it is a whole
    parameter set (a GH2010 ``best.json`` loads with ``--params``). ``sample``: a
    function of the generation giving what each of its candidates is judged on, passed to
    ``evaluate`` as ``(theta, that)`` (a noisy objective: every candidate of a generation
    on the same sample); the result is then the search's mean at the end, judged by
    ``evaluate(theta)`` alone (its whole set), not the best of the samples. ``split``
    (with workers): ``evaluate`` as jobs, (first job, jobs that follow from its result,
    run a job, combine the results), spread over the workers by ``_run_split``; it must
    give ``evaluate``'s results (``WALK_SPLIT``)."""
    from cmaes import CMA

    from stumble.jsonio import dumps

    n = len(space.names)
    opt = CMA(mean=np.zeros(n), sigma=sigma, seed=seed,
              population_size=popsize or 4 + int(3 * math.log(n)))
    best = FitResult(space.start.copy(), math.inf, {}, space=space)
    t0 = time.perf_counter()
    pool = (ProcessPoolExecutor(workers, initializer=initializer, initargs=initargs)
            if workers > 1 else None)
    split = split if pool is not None else None
    if (pool is None or split is not None) and initializer is not None:
        initializer(*initargs)
    hist_file = None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        hist_file = (out / "history.jsonl").open("a" if first_generation else "w")
    try:
        for gen in range(first_generation, first_generation + max(generations, 1)):
            # no generations: the start alone, evaluated once (its figures on record)
            xs = ([opt.ask() for _ in range(opt.population_size)] if generations
                  else [np.zeros(n)])
            thetas = [space.to_params(x) for x in xs]
            drawn = None if sample is None else sample(gen)
            args = thetas if sample is None else [(t, drawn) for t in thetas]
            if split is not None:  # each candidate as its jobs, spread over the workers
                results = _run_split(pool, split, args)
            else:
                results = list(pool.map(evaluate, args) if pool else map(evaluate, args))
            if generations:
                opt.tell([(x, r[0]) for x, r in zip(xs, results, strict=True)])
            best.evaluations += len(xs)
            costs = [r[0] for r in results]
            k = int(np.argmin(costs))
            if costs[k] < best.best_cost:
                best.best_cost, best.best_terms = costs[k], results[k][1]
                best.best_theta = thetas[k]
                if out is not None:
                    _write_json(out / "best.json", {
                        "generation": gen, "cost": costs[k], "terms": results[k][1],
                        "params": {**(fixed or {}), **dict(zip(
                            space.names, map(float, thetas[k]), strict=True))}})
            row = {"generation": gen, "stage": stage, "evaluations": best.evaluations,
                   "best": float(best.best_cost), "generation_best": float(costs[k]),
                   "generation_median": float(np.median(costs)), "sigma": float(opt._sigma),
                   "wall_time_s": round(time.perf_counter() - t0, 2),
                   "terms": {k2: round(float(v), 4) for k2, v in best.best_terms.items()}}
            best.history.append(row)
            if hist_file is not None:
                hist_file.write(dumps(row) + "\n")
                hist_file.flush()
            if progress is not None:
                progress(row)
            if target is not None and best.best_cost < target:
                break
        if sample is not None and generations:  # the mean, judged on the whole set
            theta = space.to_params(opt.mean)
            cost, terms = (pool.submit(evaluate, theta).result() if pool
                           else evaluate(theta))
            best.best_theta, best.best_cost, best.best_terms = theta, cost, terms
            if out is not None:
                _write_json(out / "best.json", {
                    "generation": "mean", "cost": cost, "terms": terms,
                    "params": {**(fixed or {}), **dict(zip(
                        space.names, map(float, theta), strict=True))}})
    finally:
        if pool is not None:
            pool.shutdown()
        if hist_file is not None:
            hist_file.close()
    best.wall_time_s = time.perf_counter() - t0
    return best


def _run_split(pool, split, args: list) -> list[tuple[float, dict]]:
    """Each candidate's (J, terms) from its jobs on the pool's workers (``split``: its
    first job, the jobs that follow from that job's result, how a job runs, how the
    results combine): every first job at once, each follow-up as soon as the job it
    follows is done; combined per candidate in its jobs' order, so the results do not
    depend on which worker ran what, or when."""
    first_job, follow_jobs, run_job, combine = split
    pending = {pool.submit(run_job, first_job(a)): (i, -1) for i, a in enumerate(args)}
    firsts: list = [None] * len(args)
    follows: list[list] = [[] for _a in args]
    while pending:
        done, _ = wait(pending, return_when=FIRST_COMPLETED)
        for fut in done:
            i, j = pending.pop(fut)
            if j >= 0:
                follows[i][j] = fut.result()
                continue
            firsts[i] = fut.result()
            jobs = follow_jobs(args[i], firsts[i])
            follows[i] = [None] * len(jobs)
            pending.update({pool.submit(run_job, job): (i, k) for k, job in enumerate(jobs)})
    return [combine(a, firsts[i], follows[i]) for i, a in enumerate(args)]


def _write_json(path: Path, obj: dict) -> None:
    """Write strict JSON atomically (a temporary name, then renamed)."""
    from stumble.jsonio import dumps

    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(dumps(obj, indent=1) + "\n")
    os.replace(tmp, path)


# ---- GH2010 --------------------------------------------------------------------------

GH2010_FIXED = ("s0", "delay_scale")  # prestimulation floor and delays stay the paper's
# offsets, thresholds and references: plain bounds; every other field is a gain or a
# prestimulation and stays within GAIN_RANGE times the paper's value, so that every
# reflex of Geyer & Herr 2010 stays active in a fitted walker (a fit left free turned the
# SOL and GAS force feedback off; at 0.2-0.4 of the paper's gains the body still walks,
# at 0.8 and more it falls: our rigid tendons make the plantarflexors' positive force
# feedback stronger than in the paper's compliant ones)
GH2010_BOUNDS = {"l_off_ta": (0.3, 1.5), "l_off_hfl": (0.3, 1.5), "l_off_ham": (0.5, 1.5),
                 "phi_off": (0.0, 0.6), "stance_load": (0.02, 0.5), "lean_ref": (-0.3, 0.4)}
GAIN_RANGE = (0.2, 5.0)
# the swing TA length reflex's bounds by name (``ta_bound``; ``--ta-bound``): ``wide``
# (the default, the shipped fits') leaves l_off_ta in GH2010_BOUNDS and g_ta in GAIN_RANGE;
# ``paper`` holds them near Geyer & Herr 2010's (0.71 l_opt, 1.1): l_off_ta within 0.6-0.8
# l_opt, g_ta within 0.5-1.5 times the paper's. The shipped trip fit's 0.37 l_opt and
# 1.7 times the paper's gain hold its foot ~37 deg toe up late in swing, so that the heel
# meets a late-swing obstacle and the foot lands on top of it (docs/reflex-fits.md); ``paper`` tests
# whether a fit kept near the paper's reflex recovers lowering trips
TA_BOUNDS = {"wide": {}, "paper": {"l_off_ta": (0.6, 0.8), "g_ta": (0.5, 1.5)}}
TA_BOUND_GAINS = ("g_ta",)  # of TA_BOUNDS: factors on the paper's value, not plain bounds
# the stumbling corrective reflex (``gh2010.SCR_GAINS``; zero in the paper): fitted only
# with trips (``stumble_reflex``), each gain in 0-1 (an excitation), steps of at least
# these
SCR_BOUNDS = {"g_scr_ham": (0.0, 1.0), "g_scr_ta": (0.0, 1.0), "g_scr_flex": (0.0, 1.0),
              "g_scr_sol": (0.0, 1.0), "g_scr_gas": (0.0, 1.0), "g_scr_glu": (0.0, 1.0),
              "g_scr_vas": (0.0, 1.0), "scr_hold_s": (0.05, 0.5),
              "scr_vas_after_s": (0.0, 0.4), "g_scr_ext_rf": (0.0, 1.0),
              "g_scr_ext_sol": (0.0, 1.0), "g_scr_ext_glu": (0.0, 1.0),
              "g_scr_ext_ham": (0.0, 1.0), "scr_ahead_m": (-0.8, 0.2)}
# the extension set acts only with ``scr_phase`` foot: fitted only then
SCR_EXTENSION = ("g_scr_ext_rf", "g_scr_ext_sol", "g_scr_ext_glu", "g_scr_ext_ham",
                 "scr_ahead_m")
# the crossing step after a touch (``gh2010.CROSS_GAINS``): fitted only with ``crossing``
CROSS_BOUNDS = {"g_cross_flex": (0.0, 1.0), "g_cross_ham": (0.0, 1.0),
                "g_cross_ta": (0.0, 1.0), "g_cross_gas": (0.0, 1.0),
                "cross_hold_s": (0.05, 0.5), "cross_ahead_m": (0.1, 0.5)}
SCR_MIN_SCALE = 0.15
# swing-leg placement (``gh2010.PLACE_FIELDS``; off in the fits before the pushed ones,
# fitted in ``pushed-walk`` and ``knee-walk``): fitted only with
# ``placement``; its gain restarts at PLACE_START where the start has it off (0)
PLACE_BOUNDS = {"k_place": (0.0, 5.0), "place_a0": (0.1, 0.6), "place_cd": (0.0, 2.0),
                "place_cv": (0.0, 1.0)}
PLACE_START = 0.5
PLACE_MIN_SCALE = {"k_place": 0.3, "place_a0": 0.05, "place_cd": 0.2, "place_cv": 0.1}


def gh2010_space(start=None, stumble_reflex: bool = False,
                 scr_phase: str | None = None, ta_bound: str = "wide",
                 crossing: bool = False, touch_only: bool = False,
                 placement: bool = False) -> Space:
    """The GH2010 gains a fit may change, scaled to about 30 % of the paper's values
    (or of ``start``'s), each within its bounds; ``stumble_reflex``: with the gains of
    the stumbling corrective reflex (``SCR_BOUNDS``; its extension set only where
    ``scr_phase``, default ``start``'s, is ``foot``); ``ta_bound``: the TA length
    reflex's bounds (``TA_BOUNDS``: ``wide``, the default, or ``paper``, near the
    paper's); ``crossing``: with the crossing step after a touch (``CROSS_BOUNDS``);
    ``touch_only``: only the reflexes a touch triggers (``SCR_BOUNDS``, ``CROSS_BOUNDS``),
    the walking gains left out (fixed); ``placement``: with the swing-leg placement
    (``PLACE_BOUNDS``). A start outside the bounds is clipped into them at the first
    candidate."""
    from stumble.control.reflex.gh2010 import GH2010Params

    p = start or GH2010Params()
    paper = GH2010Params()
    phase = scr_phase or p.scr_phase
    names = tuple(n for n in p.free() if n not in GH2010_FIXED
                  and (stumble_reflex or n not in SCR_BOUNDS)
                  and (crossing or n not in CROSS_BOUNDS)
                  and (phase == "foot" or n not in SCR_EXTENSION)
                  and (placement or n not in PLACE_BOUNDS)
                  and (not touch_only or n in SCR_BOUNDS or n in CROSS_BOUNDS))
    theta = np.array([getattr(p, n) for n in names])
    scale = np.maximum(0.3 * np.abs(theta), [
        SCR_MIN_SCALE if n in SCR_BOUNDS or n in CROSS_BOUNDS
        else PLACE_MIN_SCALE.get(n, 0.02) for n in names])
    if ta_bound not in TA_BOUNDS:
        raise ValueError(f"ta_bound must be one of {sorted(TA_BOUNDS)}, got {ta_bound!r}")
    ta = {n: (a * getattr(paper, n), b * getattr(paper, n)) if n in TA_BOUND_GAINS else (a, b)
          for n, (a, b) in TA_BOUNDS[ta_bound].items()}
    bounds = {**GH2010_BOUNDS, **SCR_BOUNDS, **CROSS_BOUNDS, **PLACE_BOUNDS, **ta}
    lo, hi = [], []
    for n in names:
        a, b = bounds.get(n, (GAIN_RANGE[0] * getattr(paper, n),
                              GAIN_RANGE[1] * getattr(paper, n)))
        lo.append(a)
        hi.append(b)
    return Space(names, theta, scale, np.array(lo), np.array(hi))


_EVAL: dict = {}


def init_walk_eval(kind: str, duration_s: float, speed_m_per_s: float, base: dict,
                   trips: tuple = (), stumble_reflex: bool = False,
                   strategy_cost: float = 0.0, crossing: bool = False,
                   foot_angle: float = 0.0, stride_time: bool = False,
                   stance_weight: float = W_STANCE, touch_only: bool = False,
                   recovery_cost: float = 0.0, placement: bool = False,
                   pushes: bool = False, track_weight: float = W_TRACK,
                   knee_weight: float = W_KNEE, starts: tuple = (),
                   timestep_s: float | None = None, trip_start: str | None = None,
                   track_limit_deg: float | None = None,
                   names: tuple[str, ...] | None = None,
                   delay_walks: tuple = (), trunk_weight: float = 0.0,
                   past_obstacle: bool = False, max_tilt_deg: float | None = None) -> None:
    """Worker set-up: what ``evaluate_walk`` simulates: a walk, and the obstacle trips
    ``trips`` ((swing fraction, speed) pairs) the walker must walk on from; GH2010
    candidates in ``gh2010_space(stumble_reflex=...)``; ``strategy_cost``: what a trip in
    a human window taken otherwise than humans take it costs (``trip_terms``);
    ``crossing``: with the crossing step's gains; ``foot_angle``, ``stride_time``,
    ``stance_weight``: the objective's foot term's weight, its stride-time term and its
    stance term's weight (``walk_cost``); ``touch_only``: candidates of the touch's
    reflexes alone (``gh2010_space(touch_only=True)``); ``recovery_cost``: what a trip not
    recovered costs on top of its time term (``trip_terms``); ``placement``: candidates
    with the swing-leg placement (``gh2010_space(placement=True)``); ``pushes``: each
    candidate also walks ``PUSH_WALK_S`` with the pelvis pushes ``PUSHES`` (``push_term``);
    ``track_weight``, ``knee_weight``: the tracking and knee terms' weights
    (``walk_cost``); ``starts``: each candidate also walks ``PUSH_WALK_S`` from the walk
    played back at each of these speeds (m/s; ``push_term``); ``timestep_s``: the network's
    physics step (default ``FIT_TIMESTEP_S``; a GH2010 candidate runs at its set's);
    ``trip_start``: where the trips start (``Scenario.start``; default the controller's);
    ``track_limit_deg``: ``walk_cost``'s; ``names``: a network candidate's parameters
    (``network_space``'s names; default inferred from its length); ``delay_walks``: each
    candidate also walks ``PUSH_WALK_S`` from the same start with its delays × each of
    these (``push_term``); ``trunk_weight``: ``walk_cost``'s; ``past_obstacle``: a trip
    recovers only past the box (``trip_outcome``; the summaries' rule since 2026-12-07,
    off for the fits made before it); ``max_tilt_deg``: nor with the trunk further than
    this from vertical at recovery-foot contact (``trip_outcome``)."""
    from stumble.pipeline import WalkInCache

    _EVAL.pop("walk", None)
    _EVAL.pop("start_net", None)
    _EVAL.update(walk_ins=WalkInCache() if touch_only else None)
    _EVAL.update(touch_only=touch_only, kind=kind, duration_s=duration_s,
                 speed=speed_m_per_s, base=base,
                 trips=tuple(trips), stumble_reflex=stumble_reflex,
                 strategy_cost=float(strategy_cost), crossing=crossing,
                 foot_angle=foot_angle, stride_time=stride_time,
                 stance_weight=float(stance_weight), recovery_cost=float(recovery_cost),
                 placement=placement, pushes=pushes, track_weight=float(track_weight),
                 knee_weight=float(knee_weight), starts=tuple(map(float, starts)),
                 timestep_s=timestep_s, trip_start=trip_start,
                 track_limit_deg=track_limit_deg, names=names,
                 delay_walks=tuple(map(float, delay_walks)),
                 trunk_weight=float(trunk_weight), past_obstacle=bool(past_obstacle),
                 max_tilt_deg=max_tilt_deg)


def _candidate(theta) -> tuple:
    """(params, network) of a candidate of the controller set up by ``init_walk_eval``
    (the one a ``gh2010`` fit does not have is None)."""
    kind = _EVAL["kind"]
    if kind == "gh2010":
        from stumble.control.reflex.gh2010 import GH2010Params

        names = gh2010_space(stumble_reflex=_EVAL.get("stumble_reflex", False),
                             scr_phase=_EVAL["base"].get("scr_phase", "any"),
                             crossing=_EVAL.get("crossing", False),
                             touch_only=_EVAL.get("touch_only", False),
                             placement=_EVAL.get("placement", False)).names
        return GH2010Params(**{**_EVAL["base"],
                               **dict(zip(names, map(float, theta), strict=True))}), None
    if kind == "network":
        from stumble.control.reflex.network import Network

        if "start_net" not in _EVAL:  # loaded once per process
            _EVAL["start_net"] = Network.load(_EVAL["base"]["network"])
        return None, network_with(_EVAL["start_net"], theta, _EVAL.get("names"))
    raise ValueError(kind)


def _own_walk(theta) -> tuple[float, dict, float]:
    """A candidate's own walk: J and terms without the extra walks and trips, and the
    walk's physics step (s), at which its extra walks run."""
    from stumble.pipeline import simulate_walk

    kind = _EVAL["kind"]
    params, net = _candidate(theta)
    touch_only = _EVAL.get("touch_only", False)
    if touch_only and "walk" in _EVAL:  # no obstacle, no touch: the same walk for every
        r = _EVAL["walk"]  # candidate, run once per process
    elif kind == "gh2010":
        r = simulate_walk("gh2010", _EVAL["duration_s"], _EVAL["speed"], params=params)
    else:
        r = simulate_walk("network", _EVAL["duration_s"], _EVAL["speed"], network=net,
                          timestep_s=_EVAL.get("timestep_s") or FIT_TIMESTEP_S)
    if touch_only:
        _EVAL["walk"] = r
    cost, terms = walk_cost(r.summary, effort_of(r), _EVAL.get("foot_angle", 0.0),
                            _EVAL.get("stride_time", False),
                            _EVAL.get("stance_weight", W_STANCE),
                            _EVAL.get("track_weight", W_TRACK),
                            _EVAL.get("knee_weight", W_KNEE),
                            _EVAL.get("track_limit_deg"),
                            _EVAL.get("trunk_weight", 0.0))
    terms["walked_s"] = r.summary["walked_s"]
    terms["speed_m_per_s"] = r.summary["speed_m_per_s"]
    return cost, terms, float(r.body.model.opt.timestep)


def _extra_walks() -> list[tuple[str, float, dict]]:
    """The extra walks of every candidate, each (term name, speed m/s, ``simulate_walk``
    options): through the pushes, from the other starts, at the other delays."""
    extra = [("push", _EVAL["speed"], {"pushes": PUSHES})] if _EVAL.get("pushes") else []
    extra += [(f"start_{v:g}", v, {}) for v in _EVAL.get("starts", ())]
    extra += [(f"delay_{k:g}", _EVAL["speed"], {"delay_scale": k})
              for k in _EVAL.get("delay_walks", ())]
    return extra


def _extra_walk(theta, speed: float, options: dict, timestep_s: float) -> dict:
    """The summary of one extra walk of a candidate, ``PUSH_WALK_S`` long."""
    from stumble.pipeline import simulate_walk

    params, net = _candidate(theta)
    return simulate_walk(_EVAL["kind"], PUSH_WALK_S, speed, params=params, network=net,
                         timestep_s=timestep_s, **options).summary


def _with_extras(cost: float, terms: dict, summaries) -> tuple[float, dict]:
    """The walk's J and terms with its extra walks' (``summaries`` in ``_extra_walks``'
    order, None for a walker that falls in its own walk: each then costs as a fall)."""
    for (name, _speed, _kw), other in zip(_extra_walks(), summaries, strict=True):
        terms[name] = push_term(other)
        cost += terms[name]
    return cost, terms


def _trip_part(theta, swing: float, speed: float) -> tuple[float, str | None]:
    """One trip of a candidate (``trip_outcome``): time walked on after it, strategy."""
    params, net = _candidate(theta)
    return trip_outcome(_EVAL["kind"], swing, speed, params, net,
                        walk_in_cache=_EVAL.get("walk_ins"), start=_EVAL.get("trip_start"),
                        timestep_s=_EVAL.get("timestep_s"),
                        past_obstacle=_EVAL.get("past_obstacle", False),
                        max_tilt_deg=_EVAL.get("max_tilt_deg"))


def _with_trips(cost: float, terms: dict, trips: tuple, outcomes) -> tuple[float, dict]:
    """The walk's J and terms with the trips' (``outcomes``: (time walked on, strategy)
    per trip, not looked at for a walker that falls)."""
    w_strategy = _EVAL.get("strategy_cost", 0.0)
    if trips and terms["fall"] == 0.0:  # trips only once it walks: they cost 3 s each
        ok = human = 0
        for (swing, speed), (t_walked, strategy) in zip(trips, outcomes, strict=True):
            terms.update(trip_terms(swing, speed, t_walked, strategy, w_strategy,
                                    _EVAL.get("recovery_cost", 0.0)))
            ok += t_walked >= WALK_ON_TRIP_S
            human += strategy is not None and strategy == human_strategy(swing)
        terms["trips_recovered"] = ok
        if w_strategy:
            terms["trips_human_strategy"] = human
        cost += sum(v for k, v in terms.items()
                    if k.startswith(("trip_", "strategy_", "unrecovered_")))
    elif trips:  # a walker that falls: every trip lost, no window trip taken as humans do
        cost += (W_TRIP + _EVAL.get("recovery_cost", 0.0)) * len(trips) + w_strategy * sum(
            human_strategy(s) is not None for s, _v in trips)
    return cost, terms


def _theta_trips(arg) -> tuple:
    """(theta, trips) of ``evaluate_walk``'s argument."""
    if isinstance(arg, tuple):
        return arg
    return arg, _EVAL.get("trips") or ()


def evaluate_walk(theta) -> tuple[float, dict]:
    """J of one candidate of the controller set up by ``init_walk_eval``; ``theta`` may be
    ``(theta, trips)``: judged on those trips instead of the set's (``cma_fit``'s
    ``sample``). The extra walks and trips run only for a walker that does not fall in
    its own walk (such a walker costs them all)."""
    first = run_walk_job(walk_first_job(theta))
    return combine_walk_jobs(theta, first, [run_walk_job(j)
                                            for j in walk_follow_jobs(theta, first)])


# ``evaluate_walk`` as jobs with a dependency (``cma_fit``'s ``split``): a candidate's own
# walk first; once it is done, and only if the walker did not fall, each of its extra
# walks and each of its trips, a job apiece; combined in that order into
# ``evaluate_walk``'s J and terms, bit for bit. So a generation's work spreads evenly over
# the workers and no work runs that is not looked at. (Before 2026-12-05, sixth session,
# only the touch stages were split, every job at once: walking fits split that way ran
# the extra walks of walkers that fall too, and were not kept.)
def walk_first_job(arg) -> tuple:
    """A candidate's first job: its own walk."""
    return ("walk", _theta_trips(arg)[0])


def walk_follow_jobs(arg, first_result) -> list[tuple]:
    """The jobs that follow a candidate's own walk (its result ``first_result``): each
    extra walk, then each trip; none when the walker fell."""
    theta, trips = _theta_trips(arg)
    if first_result[1]["fall"]:
        return []
    dt = first_result[2]
    return ([("extra", theta, speed, kw, dt) for _n, speed, kw in _extra_walks()]
            + [("trip", theta, s, v) for s, v in trips])


def run_walk_job(job: tuple):
    """One job of ``walk_first_job`` or ``walk_follow_jobs``."""
    if job[0] == "walk":
        return _own_walk(job[1])
    if job[0] == "extra":
        return _extra_walk(*job[1:])
    return _trip_part(*job[1:])


def combine_walk_jobs(arg, first_result, follow_results: list) -> tuple[float, dict]:
    """``evaluate_walk``'s J and terms from its jobs' results, in their order."""
    _theta, trips = _theta_trips(arg)
    cost, terms, _dt = first_result
    n_extra = len(_extra_walks())
    fell = bool(terms["fall"])
    cost, terms = _with_extras(cost, terms, [None] * n_extra if fell
                               else follow_results[:n_extra])
    return _with_trips(cost, terms, trips, [None] * len(trips) if fell
                       else follow_results[n_extra:])


WALK_SPLIT = (walk_first_job, walk_follow_jobs, run_walk_job, combine_walk_jobs)


W_TRIP = 20.0  # a trip the walker does not walk on from costs this (partly, if later)
WALK_ON_TRIP_S = 3.0  # walked on this long after a trip: recovered (the rule)
FIT_TRIPS = ((0.15, 1.2), (0.6, 1.2), (0.35, 1.0), (0.65, 1.4))  # (swing, m/s) obstacle


# The human strategy windows (``stumble.validate.WINDOWS`` without the middle one, where
# either strategy is human): Eng et al. 1994, Schillings et al. 2000
HUMAN_WINDOWS = ((0.05, 0.25, "elevating"), (0.55, 0.75, "lowering"))
# ``--strategy-cost`` (``fit_gh2010(strategy_cost=...)``, default 0: the objective as
# before): a trip of a stage's set in a human window whose strategy, read from the motion
# (the trip summary's ``strategy``: elevating, lowering, or none when the foot never came
# down, the trip could not be set or the walker fell before it), is not the human one
# costs this much more. W_TRIP (20) is a trip not walked on from: a cost below it still
# prefers stepping over and walking on to lowering and falling, but of two recoveries
# the human one
W_STRATEGY = 10.0  # a suggested value (not the default)


def human_strategy(swing: float) -> str | None:
    """The strategy humans take for a trip at ``swing`` of the swing (``HUMAN_WINDOWS``),
    or None between the windows, where either is human."""
    for lo, hi, strategy in HUMAN_WINDOWS:
        if lo - 1e-9 <= swing <= hi + 1e-9:
            return strategy
    return None


def trip_terms(swing: float, speed: float, walked_s: float, strategy: str | None,
               strategy_cost: float = 0.0, recovery_cost: float = 0.0) -> dict:
    """The objective's terms of one trip of a trip stage: ``trip_<swing>_<speed>``,
    ``W_TRIP`` times the part of ``WALK_ON_TRIP_S`` after it not walked on, and, when
    ``strategy_cost`` is not 0, ``strategy_<swing>_<speed>``: ``strategy_cost`` if the
    trip is in a human window (``human_strategy``) and ``strategy`` is not the human one,
    else 0; when ``recovery_cost`` is not 0, ``unrecovered_<swing>_<speed>``:
    ``recovery_cost`` if the trip was not walked on for the whole ``WALK_ON_TRIP_S``,
    else 0 (the time term alone gives a trip walked on 2.9 s nearly a recovery's
    credit)."""
    terms = {f"trip_{swing}_{speed}": W_TRIP * (1.0 - walked_s / WALK_ON_TRIP_S)}
    if strategy_cost:
        want = human_strategy(swing)
        terms[f"strategy_{swing}_{speed}"] = (
            float(strategy_cost) if want is not None and strategy != want else 0.0)
    if recovery_cost:
        terms[f"unrecovered_{swing}_{speed}"] = (
            float(recovery_cost) if walked_s < WALK_ON_TRIP_S else 0.0)
    return terms


def trip_walked_s(kind: str, swing: float, speed: float, params=None, network=None,
                  start: str | None = None) -> float:
    """How long (s, at most ``WALK_ON_TRIP_S``) a reflex walker walks on after a 10 cm
    obstacle trip (``start``: the scenario's, default the controller's), counting a fall,
    or walking no more, as the end; a fall before the trip counts as no time."""
    return trip_outcome(kind, swing, speed, params, network, start)[0]


def trip_outcome(kind: str, swing: float, speed: float, params=None, network=None,
                 start: str | None = None, walk_in_cache=None,
                 timestep_s: float | None = None,
                 past_obstacle: bool = False,
                 max_tilt_deg: float | None = None) -> tuple[float, str | None]:
    """``trip_walked_s`` and the strategy read from the motion (the trip summary's
    ``strategy``: elevating, lowering, or None when the tripped foot never came down, the
    trip could not be set or the walker fell before it). ``walk_in_cache``: a
    ``pipeline.WalkInCache`` (fits of the touch's reflexes alone); ``timestep_s``: the
    network's step (default ``FIT_TIMESTEP_S``; a GH2010 set runs at its own);
    ``past_obstacle``: a recovery needs the body past the box, as the trip summaries ask
    since 2026-12-07 (``--past-obstacle``); without it a trip counts as the fits made
    before counted it, still walking 3 s after the trip, so that their recorded commands
    re-run bit for bit (docs/reflex.md); ``max_tilt_deg``: nor a recovery whose trunk was
    further than this from vertical when the recovery foot landed (``--max-tilt``; people
    recover within about 23-26 deg, van den Bogert et al. 2002, the limit issue 11 sets
    the state machines): it costs as a trip walked on but not recovered (so a stage with
    it needs ``recovery_cost``); a recovery whose recovery foot's landing was not read
    (no tilt) still counts."""
    from stumble.errors import TripNotSet
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    sc = Scenario(controller="reflex" if kind == "network" else kind, mechanism="obstacle",
                  swing_fraction=swing, speed_m_per_s=speed, start=start,
                  duration_after_trip_s=WALK_ON_TRIP_S,
                  timestep_s=(timestep_s or FIT_TIMESTEP_S) if kind == "network" else None)
    try:
        r = simulate_trip(sc, network=network, gh2010=params, walk_in_cache=walk_in_cache,
                          past_obstacle=past_obstacle)
    except TripNotSet:  # the toe is over the obstacle at that instant of its own swing
        return 0.0, None
    s = r.summary
    if s.get("trip_time_s") is None:  # fell before the trip
        return 0.0, None
    strategy = s.get("strategy")
    tilt = s.get("trunk_tilt_at_recovery_contact_deg")
    if (s["recovered"] and max_tilt_deg is not None and tilt is not None
            and tilt > max_tilt_deg):
        return float(min(s["sim_time_s"], WALK_ON_TRIP_S - 1e-3)), strategy
    if s["recovered"]:
        return WALK_ON_TRIP_S, strategy
    if s["stop_reason"] == "stopped walking":  # upright but not walking on: half
        return 0.5 * WALK_ON_TRIP_S, strategy
    return float(min(s["sim_time_s"], WALK_ON_TRIP_S - 1e-3)), strategy


# The shipped fit: stages of (generations, walk s, obstacle trips), each continuing from
# the best of the one before; 16 candidates per generation. One stage of walking: a
# second stage of walking and tripping (0.15 and 0.6 of swing at 1.2 m/s, 0.35 at 1.0,
# 50 generations) recovered none of the three trips and lost tracking (docs/reflex-fits.md).
GH2010_STAGES = ((110, 15.0, ()),)
GH2010_POPSIZE = 16
GH2010_SPEED_M_PER_S = 1.2  # the walk played back before each candidate takes over
GH2010_SIGMA = 0.5  # initial step, in units of 30 % of each of the paper's values
GH2010_SIGMA_TRIPS = 0.3  # the trip stage starts from a walker: smaller steps


SEED003_STAGES = ((100, 10.0, ()),)  # the network's expert: walking, from SEED003_START
# The trip stage (``fit_gh2010(trips=True)``): from the walking fit, the GH2010 gains and
# the stumbling corrective reflex's on a 10 s walk and four obstacle trips in the walker's
# own gait (``Scenario.start`` own), two per strategy window and one per start speed
TRIP_STAGES = ((60, 10.0, ((0.1, 1.2), (0.3, 1.0), (0.6, 1.4), (0.72, 1.2))),)
# the trips of a trip stage by name (``--trip-set``): the four above, or twelve across
# the strategy map (swing 0.1-0.75, the three start speeds in turn), so that a fit cannot
# overfit four trips (a third four-trip stage recovered 8 of the 45: docs/reflex-fits.md)
# ``dense``: thirty, swing 0.05-0.75 in steps of 0.05 at 1.1 and 1.3 m/s, none of them
# among the 45 of the strategy map (1.0, 1.2, 1.4 m/s) or the held-out 28
# (``scripts/measure_gh2010_trips.py --grid held-out``): twelve trips were too few, a fit
# overfits them (docs/reflex-fits.md "Fitting the touch's reflexes alone"); thirty cost 2.5 times
# twelve, affordable in a ``touch_only`` stage, whose walks to the trips are cached
TRIP_SETS = {"four": TRIP_STAGES[0][2],
             "wide": ((0.1, 1.0), (0.2, 1.4), (0.3, 1.2), (0.35, 1.0), (0.4, 1.4),
                      (0.45, 1.2), (0.5, 1.0), (0.55, 1.4), (0.6, 1.2), (0.65, 1.0),
                      (0.7, 1.4), (0.75, 1.2)),
             "dense": tuple((round(0.05 * k, 2), v) for v in (1.1, 1.3) for k in range(1, 16)),
             # 116 trips at speeds and instants of neither the 45 (1.0/1.2/1.4 m/s) nor the
             # held-out 28 (1.1/1.3 m/s): a pool to draw a sample from each generation
             # (``--trip-sample``)
             "pool": tuple((round(0.05 + 0.025 * k, 3), v) for v in (1.05, 1.15, 1.25, 1.35)
                           for k in range(29))}
TRIP_SIGMA = 0.4
SCR_START = 0.2  # every gain of the stumbling corrective reflex starts here


def fit_gh2010(seed: int = 0, stages=None, popsize: int = GH2010_POPSIZE,
               workers: int = 1, out: Path | None = None, progress=None,
               wiring: str = "gh2010", trips: bool = False, start=None,
               start_fit: dict | None = None, start_from: dict | None = None,
               scr_phase: str | None = None,
               ta_bound: str = "wide", strategy_cost: float = 0.0,
               crossing: bool = False, foot_angle: float = 0.0,
               load_from: str | None = None, stride_time: bool = False,
               stance_weight: float = W_STANCE, touch_only: bool = False,
               recovery_cost: float = 0.0, placement: bool = False,
               pushes: bool = False, track_weight: float = W_TRACK,
               knee_weight: float = W_KNEE, starts: tuple = (),
               timestep_s: float | None = None, past_obstacle: bool = False) -> FitResult:
    """Optimise the GH2010 gains in closed loop: per stage (generations, walk s, obstacle
    trips), CMA-ES on ``walk_cost`` plus, for each trip, ``W_TRIP`` times the part of the
    3 s after it not walked on. ``wiring`` ``gh2010`` starts from the paper's values
    (stages ``GH2010_STAGES``), or refits the walk of ``start`` when it is given (steps of
    ``GH2010_SIGMA_TRIPS``; the gains outside the fit, a touch's reflexes among them,
    kept as ``start`` has them); ``seed003`` (the network's expert) from the first walking
    fit (``gh2010.SEED003_START``; ``SEED003_STAGES``). ``trips``: the trip stage
    (``TRIP_STAGES``) from ``start`` (default the default set's walking fit,
    ``gh2010.SHIPPED_WALKING``; ``start_fit``: how
    ``start`` was found, recorded with the result; ``start_from``: what ``--params``
    named, ``{"params": name or path, "sha256": of the file}``, recorded and put in the
    command), with the stumbling corrective reflex's
    gains: each at zero in ``start`` (never fitted, or fitted to its lower bound) restarts
    at ``SCR_START``, so that a later stage explores it again (the shipped second stage
    restarted the hip flexor's, zero after the first); ``scr_phase``: the reflex's
    phase law for the stage (``GH2010Params.scr_phase``; default ``start``'s), with its
    extension set fitted only where it is ``foot``; ``ta_bound``: the TA length reflex's
    bounds (``TA_BOUNDS``; ``wide`` as shipped, ``paper`` near the paper's), in every
    stage; ``strategy_cost`` (trip stages): what each of the stage's trips in a human
    window (``HUMAN_WINDOWS``) costs more when its strategy, read from the motion, is not
    the human one (``trip_terms``; 0, the default, leaves the objective as it was);
    ``crossing`` (trip stages): the crossing step after a touch (``CROSS_BOUNDS``) joins
    the fit, its gains restarting at ``SCR_START`` where ``start`` has them at zero;
    ``foot_angle``, ``stride_time``: the objective's foot term's weight (0, none) and
    its stride-time term (``walk_cost``), in every stage; ``stance_weight``: the stance
    term's weight (``W_STANCE``; a trip stage that lengthened the stance phase below the
    band paid 1.4 for it at weight 1, a fourteenth of a lost trip); ``load_from`` (trip stages):
    what a leg's load is (``GH2010Params.load_from``; default ``start``'s);
    ``touch_only`` (trip stages): fit only the reflexes a touch triggers (the stumbling
    corrective reflex and, with ``crossing``, the crossing step), the walking gains held
    at ``start``'s, so that the walk is the start's to the first touch;
    ``recovery_cost`` (trip stages): what each of the stage's trips not recovered costs
    on top of its time term (``trip_terms``; 0, the default, leaves the objective as it
    was); ``placement``: the swing-leg placement (``gh2010.PLACE_FIELDS``) joins the fit, in
    every stage, its gain restarting at ``PLACE_START`` where ``start`` has it off (not
    with ``touch_only``: it is a walking law); ``pushes``: every candidate also walks with
    the pelvis pushes ``PUSHES`` (``push_term``), in every stage; ``track_weight``: the
    tracking term's weight (``W_TRACK``; a trip stage weighs each lost trip as 20 to 40
    degrees of joint RMSE beyond 8°, and trades the gait for trips); ``knee_weight``:
    the knee term's (``W_KNEE``, per degree of hyperextension; 5 in ``knee-walk``'s fit, 0
    in the others); ``starts``: every candidate also walks from the walks played back at
    these speeds (m/s; ``init_walk_eval``), in every stage; ``timestep_s``: the physics
    step of every walk and trip of the fit, recorded in the result
    (``GH2010Params.timestep_s``; default ``start``'s, 1 ms for the paper's);
    ``past_obstacle``: the trips recover only past the box (``trip_outcome``). Writes
    ``gh2010.json`` to ``out`` (the best parameters and the fit's figures) when given."""
    if strategy_cost < 0 or not math.isfinite(strategy_cost):
        raise ValueError(f"strategy_cost must be a finite number >= 0, got {strategy_cost}")
    if strategy_cost and not trips:
        raise ValueError("strategy_cost is for the trip stage (trips=True)")
    if recovery_cost < 0 or not math.isfinite(recovery_cost):
        raise ValueError(f"recovery_cost must be a finite number >= 0, got {recovery_cost}")
    if recovery_cost and not trips:
        raise ValueError("recovery_cost is for the trip stage (trips=True)")
    if crossing and not trips:
        raise ValueError("crossing is for the trip stage (trips=True)")
    if not (math.isfinite(stance_weight) and stance_weight >= 0):
        raise ValueError(f"stance_weight must be a finite number >= 0, got {stance_weight}")
    if not (math.isfinite(track_weight) and track_weight >= 0):
        raise ValueError(f"track_weight must be a finite number >= 0, got {track_weight}")
    if not (math.isfinite(knee_weight) and knee_weight >= 0):
        raise ValueError(f"knee_weight must be a finite number >= 0, got {knee_weight}")
    if knee_weight and touch_only:
        raise ValueError("knee_weight weighs the walk: not with touch_only")
    if load_from is not None and not trips:
        raise ValueError("load_from is for the trip stage (trips=True)")
    if touch_only and not trips:
        raise ValueError("touch_only is for the trip stage (trips=True)")
    if placement and touch_only:
        raise ValueError("placement is a walking law: not with touch_only")
    if pushes and touch_only:
        raise ValueError("pushes test the walk: not with touch_only")
    if starts and touch_only:
        raise ValueError("starts test the walk: not with touch_only")
    from dataclasses import replace

    from stumble.control.reflex.gh2010 import (
        CROSS_GAINS,
        SCR_GAINS,
        SEED003_START,
        SHIPPED_WALKING,
        GH2010Params,
        load_params,
        shipped_params,
    )

    if trips:
        params = start or shipped_params("gh2010", walking_only=True)
        if scr_phase is not None:
            params = replace(params, scr_phase=scr_phase)
        if load_from is not None:
            params = replace(params, load_from=load_from)
        params = replace(params, **{n: getattr(params, n) or SCR_START for n in SCR_GAINS
                                    if params.scr_phase == "foot" or n not in SCR_EXTENSION})
        if crossing:
            params = replace(params, **{n: getattr(params, n) or SCR_START
                                        for n in CROSS_GAINS})
        stages = stages or TRIP_STAGES
    elif wiring == "gh2010":  # from the paper, or refitting the walk of ``start``
        params, stages = start or GH2010Params(), stages or GH2010_STAGES
    else:  # the network's expert: from the first walking fit, pinned (SEED003_START),
        # or refitting the walk of a seed003-wired ``start``
        params = start if start is not None else replace(load_params("walk"), wiring=wiring)
        stages = stages or SEED003_STAGES
    if timestep_s is not None:
        params = replace(params, timestep_s=float(timestep_s))
    total, evaluations, wall, res = 0, 0, 0.0, None
    history: list[dict] = []
    with_trips = trips
    for k, (gens, walk_s, trips) in enumerate(stages):
        if placement and not params.k_place:
            params = replace(params, k_place=PLACE_START)
        space = gh2010_space(params, stumble_reflex=with_trips, ta_bound=ta_bound,
                             crossing=crossing, touch_only=touch_only, placement=placement)
        first = k == 0 and wiring == "gh2010" and start is None  # from the paper
        sigma = (TRIP_SIGMA if with_trips else GH2010_SIGMA if first else GH2010_SIGMA_TRIPS)
        fixed = {n: v for n, v in params.to_json().items() if n not in space.names}
        res = cma_fit(evaluate_walk, space, seed=seed + k, generations=gens,
                      popsize=popsize, sigma=sigma,
                      workers=workers, out=out, progress=progress,
                      initializer=functools.partial(init_walk_eval,
                                                    past_obstacle=past_obstacle),
                      initargs=("gh2010", walk_s, GH2010_SPEED_M_PER_S,
                                fixed if with_trips or start is not None
                                else {"wiring": wiring, "timestep_s": params.timestep_s},
                                trips,
                                with_trips, strategy_cost, crossing, foot_angle,
                                stride_time, stance_weight, touch_only, recovery_cost,
                                placement, pushes, track_weight, knee_weight,
                                tuple(starts)),
                      first_generation=total, stage="walk" if not trips else "walk+trips",
                      fixed=fixed, split=WALK_SPLIT)
        params = replace(params, **dict(zip(space.names, map(float, res.best_theta),
                                            strict=True)))
        total += gens
        evaluations += res.evaluations
        wall += res.wall_time_s
        history += res.history
    res.history, res.evaluations, res.wall_time_s = history, evaluations, wall
    if out is not None:
        _write_json(out / "gh2010.json", {
            "params": params.to_json(),
            "fit": {"method": "CMA-ES (cmaes package)", "seed": seed,
                    "stages": [{"generations": g, "walk_s": w,
                                "trips": [{"swing_fraction": a, "speed_m_per_s": b}
                                          for a, b in t]} for g, w, t in stages],
                    "population": popsize, "evaluations": evaluations,
                    "sigma0": ([TRIP_SIGMA] if with_trips else [GH2010_SIGMA_TRIPS]
                               if start is not None or wiring != "gh2010"
                               else [GH2010_SIGMA, GH2010_SIGMA_TRIPS]),
                    "from": ({"params": (start_from or {}).get("params", "--params"),
                              **({"sha256": start_from["sha256"]} if start_from else {}),
                              **({"rewired_from": start_from["rewired_from"]}
                                 if "rewired_from" in (start_from or {}) else {}),
                              "its_fit": start_fit} if start is not None else
                             f"the shipped walking fit ({SHIPPED_WALKING['gh2010']})"
                             if with_trips else
                             f"the first walking fit ({SEED003_START})"
                             if wiring != "gh2010" else "the paper"),
                    "start_speed_m_per_s": GH2010_SPEED_M_PER_S,
                    "cost": res.best_cost, "terms": res.best_terms,
                    "wall_time_s": round(wall, 1),
                    "wiring": wiring,
                    "scr_phase": params.scr_phase,
                    "ta_bound": ta_bound,
                    "strategy_cost": strategy_cost,
                    "crossing": crossing,
                    "foot_angle": foot_angle,
                    "load_from": params.load_from,
                    "stride_time": stride_time,
                    "stance_weight": stance_weight,
                    "track_weight": track_weight,
                    "knee_weight": knee_weight,
                    "touch_only": touch_only,
                    "recovery_cost": recovery_cost,
                    "placement": placement,
                    "pushes": [list(q) for q in PUSHES] if pushes else [],
                    "starts": [float(v) for v in starts],
                    "timestep_s": params.timestep_s,
                    **({"past_obstacle": True} if past_obstacle else {}),
                    "command": _fit_command(wiring, with_trips, stages, scr_phase, seed,
                                            ta_bound, strategy_cost, crossing,
                                            foot_angle, load_from, stride_time,
                                            stance_weight, touch_only, recovery_cost,
                                            placement, pushes, track_weight,
                                            (start_from or {}).get("params"),
                                            knee_weight, starts, timestep_s,
                                            past_obstacle)}})
    return res


def number_text(v: float) -> str:
    """A number as a fit's recorded command writes it: whole ones short (-1, 5), others
    exactly (``repr``: 0.123456789, not ``:g``'s 0.123457), so that the command re-runs
    bit for bit; the values of every shipped command read the same either way."""
    v = float(v)
    return f"{v:g}" if v.is_integer() and abs(v) < 1e15 else repr(v)


def _fit_command(wiring: str, trips: bool, stages, scr_phase: str | None, seed: int,
                 ta_bound: str = "wide", strategy_cost: float = 0.0,
                 crossing: bool = False, foot_angle: float = 0.0,
                 load_from: str | None = None, stride_time: bool = False,
                 stance_weight: float = W_STANCE, touch_only: bool = False,
                 recovery_cost: float = 0.0, placement: bool = False,
                 pushes: bool = False, track_weight: float = W_TRACK,
                 params: str | None = None, knee_weight: float = W_KNEE,
                 starts: tuple = (), timestep_s: float | None = None,
                 past_obstacle: bool = False) -> str:
    """The ``stumble reflex fit`` command of a GH2010 fit (``params``: what ``--params``
    named, None: none given)."""
    opts = ["--trips"] if trips else []
    if params is not None:
        opts.append(f"--params {params}")
    if ta_bound != "wide":
        opts.append(f"--ta-bound {ta_bound}")
    if stride_time:
        opts.append("--stride-time")
    if stance_weight != W_STANCE:
        opts.append(f"--stance-weight {number_text(stance_weight)}")
    opts += _weight_opts(track_weight, knee_weight)
    if foot_angle:
        opts.append("--foot-angle" if foot_angle == W_FOOT
                    else f"--foot-angle {number_text(foot_angle)}")
    if placement:
        opts.append("--placement")
    if pushes:
        opts.append("--pushes")
    opts += _starts_opts(starts)
    if timestep_s is not None:
        opts.append(f"--timestep {number_text(timestep_s)}")
    if trips:
        named = [k for k, v in TRIP_SETS.items() if all(t == v for _g, _w, t in stages)]
        if named and named[0] != "four":
            opts.append(f"--trip-set {named[0]}")
        if scr_phase is not None:
            opts.append(f"--scr-phase {scr_phase}")
        opts += _trip_cost_opts(strategy_cost, recovery_cost)
        if crossing:
            opts.append("--crossing")
        if touch_only:
            opts.append("--touch-only")
        if load_from is not None:
            opts.append(f"--load-from {load_from}")
        if past_obstacle:
            opts.append("--past-obstacle")
    default = (TRIP_STAGES if trips else GH2010_STAGES if wiring == "gh2010"
               else SEED003_STAGES)
    total = sum(g for g, _w, _t in stages)
    if total != sum(g for g, _w, _t in default):
        opts.append(f"--generations {total}")
    return " ".join(["stumble reflex fit --controller gh2010 --wiring", wiring, *opts,
                     f"--seed {seed} --out DIR"])


def _trip_cost_opts(strategy_cost: float, recovery_cost: float) -> list[str]:
    """The command-line options of a trip stage's strategy and recovery costs (0: none)."""
    return ([f"--strategy-cost {number_text(strategy_cost)}"] if strategy_cost else []) + (
        [f"--recovery-cost {number_text(recovery_cost)}"] if recovery_cost else [])


def _weight_opts(track_weight: float, knee_weight: float,
                 knee_first: bool = False) -> list[str]:
    """The command-line options of the objective's tracking and knee weights that differ
    from their defaults (in the order each command has always written them)."""
    opts = [*([f"--track-weight {number_text(track_weight)}"]
              if track_weight != W_TRACK else []),
            *([f"--knee-weight {number_text(knee_weight)}"] if knee_weight != W_KNEE else [])]
    return opts[::-1] if knee_first else opts


def _starts_opts(starts: tuple) -> list[str]:
    """``--starts V,...`` when other starts are given."""
    return ["--starts " + ",".join(number_text(v) for v in starts)] if starts else []


# ---- the seed's network: a documented subset of its weights ---------------------------

BALANCE_FIT = ("kp_per_rad", "kd_s_per_rad", "lean_ref_rad", "k_lean")


def network_space(net, interneuron_biases: bool = True, touch_only: bool = False,
                  touch_response: bool = False, cross_only: bool = False) -> Space:
    """The subset of the network a closed-loop fit changes, as offsets from its weights:
    per muscle a motor-neuron gain (a factor on its summed input, ``gain_<M>``, start 1)
    and bias (``bias_<M>``, an offset on c); per interneuron an offset on its bias
    (``b_<seg>_<k>``; with ``interneuron_biases``): where each works on its tanh; the
    foot-contact afferents' weights onto the interneurons of their segments
    (``contact_<seg>_<k>``, offsets); the touch afferent's (``touch_<seg>_<k>``, offsets
    from 0, when the network has it: ``Network.with_touch``); and the trunk-lean
    addition's gains (``TrunkBalance``: k_p, k_d, θ_ref, k_lean). ``touch_response``
    (the network must have one: ``Network.with_touch_response``): its gains per set and
    muscle (``resp_<set>_<M>``, from the network's, -1 to 1) and its two durations
    (``resp_hold_s``, ``resp_after_s``; and the ahead sets' own, ``resp_hold_ahead_s``,
    ``resp_after_ahead_s``, when it has them; the recovery step's ``resp_cross_<M>`` and
    ``resp_cross_hold_s``; ``cross_only``: those alone). ``touch_only``: the touch
    afferent's weights (when the network has it) and the touch response's alone, which
    leave the walk before a touch as it is (the network's touch stage)."""
    from stumble.control.reflex.controller import TouchResponse, TrunkBalance

    t = net.topology
    resp = TouchResponse.from_info(net.info, t.muscles, t.rate_hz)
    if touch_response and resp is None:
        raise ValueError("touch_response: the network has no touch response "
                         "(Network.with_touch_response)")
    if touch_only and not (t.touch or touch_response):
        raise ValueError("touch_only: the network has no touch afferent (Network.with_touch) "
                         "and no touch response is fitted")
    names, start, scale, lo, hi = [], [], [], [], []

    def add(name, x0, sc, a, b):
        names.append(name)
        start.append(x0)
        scale.append(sc)
        lo.append(a)
        hi.append(b)

    def add_response():
        if cross_only:
            if not resp.cross:
                raise ValueError("cross_only: the response has no recovery step "
                                 "(Network.with_cross_step)")
            for m in t.muscles:
                add(f"resp_cross_{m}", resp.gains["cross"][m], 0.3, -1.0, 1.0)
            add("resp_cross_hold_s", resp.cross_hold_s, 0.05, 0.05, 0.5)
            return
        for k in resp.sets:
            for m in t.muscles:
                add(f"resp_{k}_{m}", resp.gains[k][m], 0.3, -1.0, 1.0)
        add("resp_hold_s", resp.hold_s, 0.04, 0.02, 0.25)
        add("resp_after_s", resp.after_s, 0.04, 0.0, 0.3)
        if resp.hold_ahead_s is not None:  # the ahead sets' own durations, when it has them
            add("resp_hold_ahead_s", resp.hold_ahead_s, 0.04, 0.02, 0.25)
            add("resp_after_ahead_s", resp.after_ahead_s, 0.04, 0.0, 0.3)
        if resp.cross:  # the recovery step's duration
            add("resp_cross_hold_s", resp.cross_hold_s, 0.05, 0.05, 0.5)

    if touch_only:
        for i in _touch_rows(net) if not cross_only else ():
            seg = t.segments[t.inputs()[i][0]]
            for k in range(t.hidden):
                add(f"touch_{seg}_{k}", 0.0, 1.0, -10.0, 10.0)
        if touch_response:
            add_response()
        return Space(tuple(names), np.array(start), np.array(scale), np.array(lo),
                     np.array(hi))
    for m in t.muscles:
        add(f"gain_{m}", 1.0, 0.3, 0.0, 5.0)
    for m in t.muscles:
        add(f"bias_{m}", 0.0, 1.0, -10.0, 10.0)
    if interneuron_biases:
        for seg in t.segments:
            for k in range(t.hidden):
                add(f"b_{seg}_{k}", 0.0, 0.5, -10.0, 10.0)
    if t.contact:
        for i in _contact_rows(net):
            seg = t.segments[t.inputs()[i][0]]
            for k in range(t.hidden):
                add(f"contact_{seg}_{k}", 0.0, 1.0, -10.0, 10.0)
    for i in _touch_rows(net):
        seg = t.segments[t.inputs()[i][0]]
        for k in range(t.hidden):
            add(f"touch_{seg}_{k}", 0.0, 1.0, -10.0, 10.0)
    bal = TrunkBalance.from_info(net.info)
    for n, x0 in zip(BALANCE_FIT, (bal.kp, bal.kd, bal.ref, bal.k_lean or 0.5), strict=True):
        add(f"balance_{n}", x0, max(0.3 * abs(x0), 0.05), -0.5 if n == "lean_ref_rad" else 0.0,
            10.0)
    if touch_response:
        add_response()
    return Space(tuple(names), np.array(start), np.array(scale), np.array(lo), np.array(hi))


def _contact_rows(net) -> list[int]:
    """Indices of the foot-contact inputs among the network's inputs."""
    t = net.topology
    return [i for i, (_s, sig, _lag) in enumerate(t.inputs()) if sig == 3 * t.n_muscles]


def _touch_rows(net) -> list[int]:
    """Indices of the touch inputs among the network's inputs (none without it)."""
    return net.topology.touch_inputs()


def network_with(net, theta: np.ndarray, names: tuple[str, ...] | None = None):
    """A copy of ``net`` with a ``network_space`` candidate applied; ``names``: the
    candidate's parameters (default: the whole subset, with the interneurons' biases when
    ``theta`` is that long). A touch stage's candidate (``touch_only``) changes only the
    touch afferent's weights."""
    from dataclasses import replace as _replace

    t = net.topology
    if names is None:
        with_b = len(theta) > len(network_space(net, False).names)
        names = network_space(net, interneuron_biases=with_b).names
    p = dict(zip(names, map(float, theta), strict=True))
    v, c, w, b = net.v.copy(), net.c.copy(), net.w.copy(), net.b.copy()
    H = t.hidden
    for i in _touch_rows(net):
        s = t.inputs()[i][0]
        seg = t.segments[s]
        for k in range(H):
            w[i, s * H + k] += p.get(f"touch_{seg}_{k}", 0.0)
    info = dict(net.info)
    if any(n.startswith("resp_") for n in names):  # the touch response: its values
        from stumble.control.reflex.controller import TouchResponse

        resp = dict(info["touch_response"])
        for k in TouchResponse.SETS + TouchResponse.AHEAD_SETS + (TouchResponse.CROSS,):
            if f"resp_{k}_{t.muscles[0]}" in p:
                resp[k] = {m: p[f"resp_{k}_{m}"] for m in t.muscles}
        if "resp_hold_s" in p:
            resp["hold_s"], resp["after_s"] = p["resp_hold_s"], p["resp_after_s"]
        if "resp_hold_ahead_s" in p:
            resp["hold_ahead_s"] = p["resp_hold_ahead_s"]
            resp["after_ahead_s"] = p["resp_after_ahead_s"]
        if "resp_cross_hold_s" in p:
            resp["cross_hold_s"] = p["resp_cross_hold_s"]
        info["touch_response"] = resp
    if all(n.startswith(("touch_", "resp_")) for n in names):  # the touch stage: nothing
        return _replace(net, w=w, info=info)  # else moves
    for s, seg in enumerate(t.segments):
        for k in range(t.hidden):
            b[s * t.hidden + k] += p.get(f"b_{seg}_{k}", 0.0)
    for k, (_s, j, _lag) in enumerate(t.connections()):
        v[k] *= p[f"gain_{t.muscles[j]}"]
    for j, m in enumerate(t.muscles):
        c[j] = c[j] * p[f"gain_{m}"] + p[f"bias_{m}"]
    for i in _contact_rows(net):
        s = t.inputs()[i][0]
        seg = t.segments[s]
        for k in range(H):
            w[i, s * H + k] += p[f"contact_{seg}_{k}"]
    bal = dict(info.get("balance") or {})
    bal.update({n: p[f"balance_{n}"] for n in BALANCE_FIT})
    bal.setdefault("rectified", True)
    info["balance"] = bal
    return _replace(net, w=w, b=b, v=v, c=c, info=info)


# ---- the seed's network: an evolution strategy on a documented subset -----------------

# ``reflex fit --controller network --walk-es NETWORK`` (ours, since 2026-12-04): CMA-ES on
# ``network_space`` of a shipped or saved network, on the walking objective (``walk_cost``)
# of a NETWORK_ES_WALK_S walk from the 1.2 m/s recording, with the options of the GH2010
# walking fits (knee and tracking weights, other starts). Steps of NETWORK_ES_SIGMA in
# units of each parameter's scale, as the GH2010 trip stages take from a walker.
NETWORK_ES_GENERATIONS = 150
NETWORK_ES_WALK_S = 15.0
NETWORK_ES_SIGMA = 0.3


def parse_set_response(text: str) -> dict:
    """``reflex fit --set-response``'s ``SET.MUSCLE=GAIN[,...]`` as ``{set: {muscle:
    gain}}`` (checked against a network by ``Network.with_response_gains``)."""
    out: dict = {}
    for item in (text or "").split(","):
        key, eq, value = item.strip().partition("=")
        k, dot, m = key.strip().partition(".")
        try:
            v = float(value)
        except ValueError:
            v = None
        if not (eq and dot and k and m and v is not None and math.isfinite(v)):
            raise InputError(f"--set-response {text!r}: {item.strip()!r} is not "
                             "SET.MUSCLE=GAIN (e.g. contra_ahead.HFL=1)")
        if m.strip() in out.get(k.strip(), {}):
            raise InputError(f"--set-response: {k.strip()}.{m.strip()} is given twice")
        out.setdefault(k.strip(), {})[m.strip()] = v
    return out


def set_response_text(gains: dict) -> str:
    """``parse_set_response``'s text of ``{set: {muscle: gain}}``, in their order, each
    gain exactly (``number_text``), so that the recorded command re-runs bit for bit."""
    return ",".join(f"{k}.{m}={number_text(v)}" for k, g in gains.items()
                    for m, v in g.items())


def fit_network_es(start, start_from: dict, seed: int = 0,
                   generations: int = NETWORK_ES_GENERATIONS, workers: int = 1,
                   out: Path | None = None, progress=None, knee_weight: float = W_KNEE,
                   track_weight: float = W_TRACK, starts: tuple = (),
                   timestep_s: float | None = None, interneuron_biases: bool = False,
                   sigma: float = NETWORK_ES_SIGMA, trips: tuple = (),
                   strategy_cost: float = 0.0, recovery_cost: float = 0.0,
                   trip_start: str | None = None, touch: bool = False,
                   track_limit_deg: float | None = None, touch_only: bool = False,
                   touch_response: bool = False, response_by_foot: bool = False,
                   ahead_from: tuple | None = None, trip_sample: int | None = None,
                   cross_step: bool = False, cross_only: bool = False,
                   delay_walks: tuple = (), pushes: bool = False,
                   trunk_weight: float = 0.0, past_obstacle: bool = False,
                   set_response: dict | None = None, max_tilt_deg: float | None = None):
    """CMA-ES on ``network_space(start, interneuron_biases, touch_only, touch_response)``:
    each candidate walks
    ``NETWORK_ES_WALK_S`` from the 1.2 m/s recording (and 10 s from each of ``starts``) at
    ``timestep_s`` (default the step the network runs at, ``trip.DEFAULT_TIMESTEP_S``:
    2 ms; DAgger keeps ``FIT_TIMESTEP_S``), costed by ``walk_cost`` with
    ``knee_weight`` and ``track_weight``. ``start_from``: what was named (``{"network":
    name or path, "sha256": ...}``), recorded with the result. Returns (the best network,
    with its fit in ``info["fit"]``, and the ``FitResult``); ``sigma``: CMA-ES's first
    step in units of each parameter's scale (smaller for a second stage from a fitted
    network); ``trips``: obstacle trips ((swing fraction, m/s) pairs, e.g. a
    ``TRIP_SETS`` entry) each candidate that walks must walk on from, costed by
    ``trip_terms`` with ``strategy_cost`` and ``recovery_cost``, started at
    ``trip_start`` (``Scenario.start``: ``own`` or ``playback``; default the network's,
    ``own`` since 2026-12-06, ``playback`` before: every recorded command names it);
    ``touch``: give the start the touch afferent first (``Network.with_touch``: its
    weights join the subset, from 0); ``track_limit_deg``: ``walk_cost``'s (each joint's
    RMSE beyond it costs ``W_TRACK_LIMIT`` a degree);
    ``touch_only``: the network's touch stage, the touch afferent's weights alone (given
    the afferent first if the start has none): the walk stays the start's, bit for bit, so
    it is run once per worker and each trip's walk to the trip once (``WalkInCache``);
    it needs ``trips`` and takes no ``starts``; ``touch_response``: give the start a touch
    response first if it has none (``Network.with_touch_response``, gains 0): its gains
    and durations join the subset (``response_by_foot``: with sets for a touch of the foot
    ahead, ``TouchResponse.by_foot``; a response that is not by the foot is copied to
    both feet first); ``ahead_from``: (a network, what was named) whose response by the
    foot gives the start's for the foot ahead first (``Network.with_ahead_response``);
    ``cross_step``: give the response the recovery step's set first
    (``Network.with_cross_step``, gains 0); ``cross_only``: fit that set alone (with
    ``touch_only``); ``trip_sample``: each generation's
    candidates judged on that many of ``trips``,
    drawn afresh each generation (seeded by ``seed`` and the generation), the result the
    search's mean at the end judged on all of them (``cma_fit``'s ``sample``);
    ``delay_walks``: each candidate also walks 10 s from the 1.2 m/s recording with its
    delays × each of these (``init_walk_eval``'s; not with ``touch_only``); ``pushes``:
    each candidate also walks 10 s from it through the pelvis pushes ``PUSHES``
    (``init_walk_eval``'s, as Geyer & Herr's ``--pushes``; not with ``touch_only``);
    ``trunk_weight``: ``walk_cost``'s trunk term (0, none; not with ``touch_only``);
    ``past_obstacle``: the trips recover only past the box (``trip_outcome``);
    ``set_response``: ``{set: {muscle: gain}}`` of the touch response set by hand first
    (``Network.with_response_gains``; with ``generations`` 0, the result);
    ``max_tilt_deg``: a trip's recovery counts only with the trunk within this of vertical
    at recovery-foot contact (``trip_outcome``);
    writes ``network.npz``,
    ``history.jsonl`` and ``best.json`` to ``out`` when given."""
    import tempfile

    if not (math.isfinite(knee_weight) and knee_weight >= 0):
        raise ValueError(f"knee_weight must be a finite number >= 0, got {knee_weight}")
    if not (math.isfinite(track_weight) and track_weight >= 0):
        raise ValueError(f"track_weight must be a finite number >= 0, got {track_weight}")
    from stumble.trip import DEFAULT_TIMESTEP_S

    if touch_only and not trips:
        raise ValueError("touch_only is for trips: name a trip set")
    if touch_only and (starts or delay_walks or pushes):
        raise ValueError("starts, delay_walks and pushes test the walk: not with touch_only")
    for k in delay_walks:
        if not (math.isfinite(k) and 0.5 <= k <= 3.0):
            raise ValueError(f"delay_walks take delay scales of 0.5-3, got {k}")
    if touch_only and interneuron_biases:
        raise ValueError("interneuron_biases change the walk: not with touch_only")
    if touch or (touch_only and not touch_response and not start.topology.touch):
        start = start.with_touch()
    if response_by_foot and not touch_response:
        raise ValueError("response_by_foot is for touch_response")
    if touch_response:
        start = start.with_touch_response(by_foot=response_by_foot)
    if ahead_from is not None:
        if not response_by_foot:
            raise ValueError("ahead_from is for response_by_foot")
        start = start.with_ahead_response(ahead_from[0])
    if cross_step:
        if not touch_response:
            raise ValueError("cross_step is for touch_response")
        start = start.with_cross_step()
    if cross_only and not (touch_only and cross_step):
        raise ValueError("cross_only is for touch_only with cross_step")
    if set_response:
        if not touch_response:
            raise ValueError("set_response is for touch_response")
        start = start.with_response_gains(set_response)
    space = network_space(start, interneuron_biases=interneuron_biases,
                          touch_only=touch_only, touch_response=touch_response,
                          cross_only=cross_only)
    step = timestep_s or DEFAULT_TIMESTEP_S["reflex"]
    sample = None
    if trip_sample is not None:
        if not 1 <= trip_sample <= len(trips):
            raise ValueError(f"trip_sample must be 1-{len(trips)} (the trip set's size), "
                             f"got {trip_sample}")
        drawable = tuple(trips)

        def sample(gen: int) -> tuple:
            rng = np.random.default_rng([seed, gen])
            return tuple(drawable[i] for i in sorted(rng.choice(len(drawable), trip_sample,
                                                            replace=False)))
    with tempfile.TemporaryDirectory() as tmp:  # the workers load the start from a file
        path = Path(tmp) / "start.npz"
        start.save(path)
        res = cma_fit(evaluate_walk, space, seed=seed, generations=generations,
                      sigma=sigma, workers=workers, out=out, progress=progress,
                      initializer=functools.partial(
                          init_walk_eval, "network", NETWORK_ES_WALK_S,
                          GH2010_SPEED_M_PER_S, {"network": str(path)}, trips=tuple(trips),
                          strategy_cost=float(strategy_cost),
                          recovery_cost=float(recovery_cost), track_weight=track_weight,
                          knee_weight=knee_weight, starts=tuple(starts), timestep_s=step,
                          trip_start=trip_start, track_limit_deg=track_limit_deg,
                          touch_only=touch_only, names=tuple(space.names),
                          delay_walks=tuple(delay_walks), pushes=pushes,
                          trunk_weight=trunk_weight, past_obstacle=past_obstacle,
                          max_tilt_deg=max_tilt_deg),
                      stage="walk+trips" if trips else "walk", sample=sample,
                      split=WALK_SPLIT)
    net = network_with(start, res.best_theta, space.names)
    opts = [*_weight_opts(track_weight, knee_weight, knee_first=True), *_starts_opts(starts),
            f"--timestep {number_text(step)}"]  # always: the default step may change
    if delay_walks:
        opts.append("--delay-walks " + ",".join(number_text(k) for k in delay_walks))
    if pushes:
        opts.append("--pushes")
    if interneuron_biases:
        opts.append("--interneuron-biases")
    if touch and not touch_only:
        opts.append("--touch-afferent")
    if touch_only:
        opts.append("--touch-only")
    if touch_response:
        opts.append("--touch-response")
    if response_by_foot:
        opts.append("--scr-phase foot")
    if ahead_from is not None:
        opts.append(f"--ahead-from {ahead_from[1]['network']}")
    if cross_step:
        opts.append("--cross-step")
    if cross_only:
        opts.append("--cross-only")
    if set_response:
        opts.append(f"--set-response {set_response_text(set_response)}")
    if track_limit_deg is not None:
        opts.append(f"--track-limit {number_text(track_limit_deg)}")
    if trunk_weight:
        opts.append(f"--trunk-weight {number_text(trunk_weight)}")
    if generations != NETWORK_ES_GENERATIONS:
        opts.append(f"--generations {generations}")
    if sigma != NETWORK_ES_SIGMA:
        opts.append(f"--sigma {number_text(sigma)}")
    if trips:
        name = next((k for k, v in TRIP_SETS.items() if tuple(v) == tuple(trips)), None)
        opts.append(f"--trip-set {name}" if name else f"(trips {list(trips)})")
        opts += _trip_cost_opts(strategy_cost, recovery_cost)
        if trip_start:
            opts.append(f"--trip-start {trip_start}")
        if trip_sample is not None:
            opts.append(f"--trip-sample {trip_sample}")
        if past_obstacle:
            opts.append("--past-obstacle")
        if max_tilt_deg is not None:
            opts.append(f"--max-tilt {number_text(max_tilt_deg)}")
    command = " ".join(["stumble reflex fit --controller network --walk-es",
                        str(start_from.get("network")), *opts, f"--seed {seed} --out DIR"])
    info = dict(net.info)
    info["fit"] = {"method": ("CMA-ES (cmaes package) on fit_walk.network_space"
                              if generations else "none: the start as given (--generations "
                              "0), its objective evaluated once"),
                   "seed": seed, "generations": generations,
                   "population": len(res.history) and res.evaluations // len(res.history),
                   "evaluations": res.evaluations, "sigma0": sigma,
                   "from": ({**start_from, "its_fit": start.info["fit"]}
                            if (start.info or {}).get("fit") else start_from),
                   "parameters": list(space.names),
                   "theta": [float(x) for x in res.best_theta],
                   "walk_s": NETWORK_ES_WALK_S, "start_speed_m_per_s": GH2010_SPEED_M_PER_S,
                   "knee_weight": knee_weight, "track_weight": track_weight,
                   "starts": [float(v) for v in starts], "timestep_s": step,
                   **({"delay_walks": [float(k) for k in delay_walks]}
                      if delay_walks else {}),
                   **({"pushes": [list(q) for q in PUSHES]} if pushes else {}),
                   "trips": [list(t) for t in trips], "strategy_cost": strategy_cost,
                   "recovery_cost": recovery_cost, "trip_start": trip_start,
                   "touch_afferent": bool(start.topology.touch), "touch_only": touch_only,
                   "touch_response": touch_response,
                   **({"ahead_from": ahead_from[1]} if ahead_from is not None else {}),
                   **({"set_response": set_response_text(set_response)}
                      if set_response else {}),
                   **({"trip_sample": trip_sample, "result": "the search's mean at the "
                       "end, judged on the whole trip set"} if trip_sample else {}),
                   "track_limit_deg": track_limit_deg,
                   **({"trunk_weight": trunk_weight} if trunk_weight else {}),
                   **({"past_obstacle": True} if past_obstacle else {}),
                   **({"max_tilt_deg": max_tilt_deg} if max_tilt_deg is not None else {}),
                   "cost": res.best_cost, "terms": res.best_terms,
                   "wall_time_s": round(res.wall_time_s, 1), "command": command}
    from dataclasses import replace as _replace

    net = _replace(net, info=info)
    if out is not None:
        net.save(out / "network.npz")
    return net, res
