"""Random or local search over the free targets of the FSM trip controllers (reproducible).

SCA 2009 §6: "the proportional gains of each joint/state and the trajectories for the
limbs were tuned manually". We tune the targets that the paper took from its own trip
motion capture, within ranges grounded in the literature (the defaults' comments in
``stumble/control/fsm_params.py``), against a fixed grid of force trips, maximising
the number recovered (tie-break: the time survived). Seeded and deterministic.

Run:  python scripts/tune_fsm.py [--candidates N] [--workers N] [--seed S]
      [--grid small|full|lowering|full+bodies]
      [--only all|lowering|lowering_fast|lowering_flight] [--around JSON]
      [--method random|cma] [--generations G] [--popsize P] [--out FILE]
      [--strength anderson2007|fixed] [--trunk-attitude K] [--max-tilt DEG]
      [--grid-floor N] [--walk-on S] [--walk-on-gait W] [--flight W]
      [--rec-hip-cap NM] [--sup-hip-cap NM] [--sup-knee-cap NM] [--push-off W]
      [--push-off-knee K] [--bodies-floor N] [--flight-from-fall] [--flight-targets]
      [--over-tilt W] [--unsettled W]
``--method cma``: CMA-ES (the ``cmaes`` package, seeded) over the targets scaled to
their ranges, from the defaults, maximising recoveries + the fraction of the grid's
time survived; the best so far is written to ``--out`` as it goes, and every
generation's best to FILE with the suffix ``.generations.jsonl`` (one record a line).
``--rec-hip-cap NM``: every candidate runs with the recovery hip's servo capped at NM
N·m in the push-off (``FSMParams.push_off_rec_hip_limit_nm``, a setting of the file);
``--sup-hip-cap NM`` the support hip's attitude servo (``push_off_hip_limit_nm``),
``--sup-knee-cap NM`` the support knee's servo (``push_off_sup_knee_limit_nm``).
``--push-off W``: the objective loses W for each of validate's nine mid-swing obstacle
trips of the full grid (0.25-0.45 of swing) by how far its support limb's peak hip
extension and knee flexion moments in the first 300 ms exceed 1.5 times Pijnappels et
al. 2005's means (52 and 54 N·m): max(0, hip/78 − 1) + K·max(0, knee/81 − 1), K 1
unless ``--push-off-knee K``. ``--bodies-floor N`` (``full+bodies``): the objective
loses 2 per body trip recovered below N, as ``--grid-floor`` does for the grid's.
``--over-tilt W`` (with ``--max-tilt DEG``): the objective loses W per trip that walks
on with the trunk past DEG at recovery-foot contact (such a trip already does not count
as recovered; the term pushes the search away from it too).
``--unsettled W`` (with ``--walk-on S``): the objective loses W per trip that walks on
(within ``--max-tilt`` or not) and never settles (``unsettled``: no steady gait in the
time budget, or a heading more than ``HEADING_LIMIT_DEG`` from the walk before; issue
11: the person "settles into a steady gait").
``--flight-from-fall``: every candidate enters Flight when its support foot leaves the
floor in Fall (``FSMParams.flight_from_fall``, written to the ``--out`` file's settings);
``--flight-targets`` searches both Flight tables' targets too (``ELEV_FLIGHT`` and the
lowering's ``fl_low_*``).
``--max-tilt DEG``: a recovery counts only with the trunk within DEG of vertical at
recovery-foot contact; ``--grid-floor N``: the objective loses 2 per trip of the first
48 (the full grid; with ``full+bodies`` the bodies follow) recovered below N.
``--only lowering`` searches the lowering strategy's own targets (``LOWERING``): the
trips the start sends to the elevating strategy do not use them, so they run once, with
the start's values, and every candidate runs only the lowering trips (the score is the
same as running all; ``src/stumble/control/fsm_test.py``): 54 of the 144 ``full+bodies`` trips.
``--only lowering_fast`` searches those and the lowering Fall's offsets at fast walking
(``LOWERING_FAST``: ``FSMParams.low_fall_fast_deg``), on the same trips;
``--only lowering_flight`` those and the lowering's flight (``LOWERING_FLIGHT``: its own
k_c at fast walking, the COM's lead over the lowered foot before it pushes, its own
Flight table).
Prints the best parameter set as JSON, to be carried into fsm_params.py by hand.

The ``--out`` file is a state-machine parameter file (``stumble trip --params FILE``,
``stumble study --params FILE``, ``fsm_params.load_params``): ``"params"`` holds the
searched values, ``"settings"`` the ``trunk_attitude`` and ``attitude_damping`` every
candidate ran with (``--trunk-attitude``, ``--attitude-damping``). ``--around`` takes
such a file (its path), or JSON text: such a file's text or a bare object of SPACE names
(``"$(cat scripts/fsm_start_trunk.json)"``). A file's settings become the search's
unless the option is given; an explicit option that differs from the file's setting is
refused (the start values were found with the file's), so give the same value or leave
it out.
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

# name: (path in FSMParams, lo, hi)
from stumble.control.fsm_params import (
    ELEV_FLIGHT,
    FLIGHT,
    GAINS,
    LATERAL,
    LOWERING_FLIGHT,
    SPACE,
    TUNABLE,
    WALK_ON,
)

# the targets that only the lowering strategy uses (--only lowering)
LOWERING = ("low_sup_ankle", "low_rec_hip", "low_rec_knee", "low_rec_ankle", "swap_trip_hip",
            "swap_trip_ankle", "swap_trip_knee", "ds_low_sup_knee", "ds_low_sup_hip",
            "ssat_low_sup_hip", "ssat_low_sup_knee", "ssat_low_sup_ankle")
GRID = [(f, v, mech) for mech in ("force", "obstacle") for f in (0.1, 0.3, 0.45, 0.55, 0.65, 0.75)
        for v in (1.0, 1.4)]
# the grid: swing 0.05-0.75, 1.0-1.4 m/s, both mechanisms (--grid full)
FULL_GRID = [(f, v, mech) for mech in ("force", "obstacle")
             for f in (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75) for v in (1.0, 1.2, 1.4)]
# the lowering Fall's offsets at fast walking (--only lowering_fast; FSMParams.
# low_fall_fast_deg): used by lowering trips alone, as LOWERING
LOWERING_FAST = tuple(k for k in FLIGHT if k.startswith("low_fall_"))
# the walk on's own parameters and the reaching leg's (--only walk_on)
WALK_ON_NAMES = (*WALK_ON, "reach_thigh_deg", "reach_sup_knee")
# the lowering half of the grid (auto chooses lowering above 0.5 of swing)
LOWERING_GRID = [(f, v, mech) for mech in ("force", "obstacle") for f in (0.55, 0.65, 0.75)
                 for v in (1.0, 1.2, 1.4)]
# the six bodies (height m, mass kg, sex) at 1.2 m/s, swing 0.05-0.75, both
# mechanisms (docs/trips.md "Any body"); --grid full+bodies adds them to the full grid
BODIES = ((1.50, 45.0, "female"), (1.65, 60.0, "female"), (1.70, 85.0, "female"),
          (1.70, 80.0, "male"), (1.90, 90.0, "male"), (1.95, 110.0, "male"))
BODY_GRID = [(f, 1.2, mech, *body) for body in BODIES for mech in ("force", "obstacle")
             for f in (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75)]
# the value sets --only chooses among (search_space)
ONLY = ("all", "lowering", "lowering_fast", "lowering_flight", "walk_on", "all+walk_on")


def search_space(only: str, gains: bool, lateral: bool = False,
                 flight_targets: bool = False) -> dict:
    """The values a search varies (name: (path, low, high)) for ``--only``, ``--gains``,
    ``--lateral`` and ``--flight-targets``."""
    if only == "walk_on":
        space = {k: TUNABLE[k] for k in WALK_ON_NAMES}
    elif only == "lowering_fast":
        space = {k: TUNABLE[k] for k in (*LOWERING, *LOWERING_FAST)}
    elif only == "lowering_flight":
        space = {k: TUNABLE[k] for k in (*LOWERING, *LOWERING_FAST, *LOWERING_FLIGHT)}
    else:
        space = {k: v for k, v in SPACE.items() if only != "lowering" or k in LOWERING}
        if only == "all+walk_on":
            space.update({k: TUNABLE[k] for k in WALK_ON_NAMES})
    if gains:
        space.update(GAINS)
    if lateral:
        space.update(LATERAL)
    if flight_targets:  # both Flight tables' targets; a lowering search the lowering's
        if only not in ("lowering", "lowering_fast", "lowering_flight"):
            space.update(ELEV_FLIGHT)  # (its elevating trips run once, with the start's)
        space.update({k: v for k, v in LOWERING_FLIGHT.items() if k.startswith("fl_low_")})
    return space


ATTITUDE_DAMPING = "joint"  # --attitude-damping (FSMParams.attitude_damping)
REC_HIP_CAP = None  # --rec-hip-cap (FSMParams.push_off_rec_hip_limit_nm)
SUP_HIP_CAP = None  # --sup-hip-cap (FSMParams.push_off_hip_limit_nm)
SUP_KNEE_CAP = None  # --sup-knee-cap (FSMParams.push_off_sup_knee_limit_nm)
FLIGHT_FROM_FALL = False  # --flight-from-fall (FSMParams.flight_from_fall)
TRUNK_ATTITUDE = 0.0  # --trunk-attitude (FSMParams.trunk_attitude)


def read_around(text: str) -> tuple[dict, dict]:
    """The start values of ``--around`` and its checked settings ({}: none):
    ``text`` is JSON text or the path of a JSON file, either a parameter file
    (``{"params": {...}, "settings": {...}}``, as ``--out`` writes it) or a bare object of
    SPACE/GAINS names. InputError (one line) names a bad file or setting."""
    from pathlib import Path

    from stumble.control.fsm_params import check_setting
    from stumble.errors import InputError

    where = "--around"
    if not text.lstrip().startswith("{"):  # a path
        where = text
        try:
            text = Path(text).read_text()
        except (OSError, ValueError) as e:
            raise InputError(f"{where}: cannot be read ({type(e).__name__})") from None
    try:
        doc = json.loads(text)
    except ValueError:
        raise InputError(f"{where}: not JSON") from None
    if not isinstance(doc, dict):
        raise InputError(f"{where}: not a JSON object")
    if "params" not in doc:
        return doc, {}
    values, settings = doc["params"], doc.get("settings", {})
    if not isinstance(values, dict) or not isinstance(settings, dict):
        raise InputError(f"{where}: \"params\" and \"settings\" must be JSON objects")
    return dict(values), {name: check_setting(name, value, where)
                          for name, value in settings.items()}


def setting_of(name: str, explicit, from_file: dict, option: str | None = None):
    """The search's setting ``name``: its option's value (``explicit``, None when not
    given), else the ``--around`` file's (``from_file``, read_around's settings), else
    FSMParams' default; the option (``option``, default ``--`` and the name) and the file
    both given and different: InputError."""
    from stumble.control.fsm_params import FSMParams
    from stumble.errors import InputError

    option = option or "--" + name.replace("_", "-")
    if explicit is not None and name in from_file and explicit != from_file[name]:
        raise InputError(f"{option} {explicit} conflicts with the --around file's "
                         f"settings.{name} {from_file[name]}: give the same value or "
                         f"leave {option} out")
    if explicit is not None:
        return explicit
    return from_file[name] if name in from_file else getattr(FSMParams(), name)


def settings() -> dict:
    """The settings every candidate runs with (a parameter file's ``"settings"``)."""
    return {"trunk_attitude": TRUNK_ATTITUDE, "attitude_damping": ATTITUDE_DAMPING,
            "push_off_rec_hip_limit_nm": REC_HIP_CAP, "push_off_hip_limit_nm": SUP_HIP_CAP,
            "push_off_sup_knee_limit_nm": SUP_KNEE_CAP, "flight_from_fall": FLIGHT_FROM_FALL}


def out_record(best: tuple, generation: int, argv: list[str]) -> dict:
    """The ``--out`` file: the best so far as a parameter file (``params`` and
    ``settings``, ``fsm_params.load_params``) with its score, the generation that found
    it (−1: the start) and the command."""
    return {"recovered": best[1][0], "of": len(GRID), "grid_recovered": best[1][2],
            "survived_s": round(best[1][1], 3), "generation": generation,
            "gait_bonus": round(best[1][3], 3), "flight_score": best[1][4],
            "push_off_excess": round(best[1][5], 3), "over_tilt": best[1][6],
            "unsettled": best[1][7],
            "command": " ".join(["python scripts/tune_fsm.py", *argv]),
            "params": best[0], "settings": settings()}


def params_from(x: dict):
    """An FSMParams with the searched values set."""
    from dataclasses import replace

    from stumble.control.fsm_params import FSMParams

    return replace(FSMParams(), attitude_damping=ATTITUDE_DAMPING,
                   trunk_attitude=TRUNK_ATTITUDE,
                   push_off_rec_hip_limit_nm=REC_HIP_CAP,
                   push_off_hip_limit_nm=SUP_HIP_CAP,
                   push_off_sup_knee_limit_nm=SUP_KNEE_CAP,
                   flight_from_fall=FLIGHT_FROM_FALL).with_values(x)


STRENGTH = "fixed"  # the servos' torque limits (Scenario.strength_model, --strength)
WALK_ON_S = None  # --walk-on S: recovered = still walking S s after the trip
MAX_TILT = None  # --max-tilt DEG: a recovery counts only with the trunk within DEG
GRID_FLOOR = None  # --grid-floor N: penalise grid recoveries (the first 48) below N
GAIT_WEIGHT = 0.0  # --walk-on-gait W: a walk on like the walk before is worth 1 + W
GAIT_SCALE = 0.4  # the gait_mismatch at which that bonus ends (e.g. 20 % off in each)
FLOOR_N, FLOOR_PENALTY = len(FULL_GRID), 2.0
FLIGHT_WEIGHT = 0.0  # --flight W: a recovery with a flight where people fly is worth 1 + W
PUSH_WEIGHT = 0.0  # --push-off W: the objective loses W × push_off_excess of each trip
KNEE_WEIGHT = 1.0  # --push-off-knee K: the knee's term of push_off_excess counts K times
BODIES_FLOOR = None  # --bodies-floor N: 2 lost per body trip recovered below N
OVER_TILT_WEIGHT = 0.0  # --over-tilt W: W lost per trip walking on past MAX_TILT
UNSETTLED_WEIGHT = 0.0  # --unsettled W: W lost per trip walking on that never settles
# a walk on heading further than this from the walk before has not settled (--unsettled);
# our choice: the default set's 47 grid walks on turn at most 16.1° (2026-12-07); two of
# its 90 body walks on turn 23.8° and 24.1°, so it scores 2 unsettled over full+bodies
HEADING_LIMIT_DEG = 20.0


def counts(s: dict) -> bool:
    """Whether a trip's summary counts as recovered (and within ``MAX_TILT``)."""
    if not s["recovered"]:
        return False
    tilt = s.get("trunk_tilt_at_recovery_contact_deg")
    return MAX_TILT is None or (tilt is not None and tilt <= MAX_TILT)


def over_tilt(s: dict) -> bool:
    """Whether a trip walks on with the trunk past ``MAX_TILT`` at recovery-foot contact
    (a recovery people would not make: issue 11's "no recovery beyond 26°")."""
    tilt = s.get("trunk_tilt_at_recovery_contact_deg")
    return bool(s["recovered"] and MAX_TILT is not None and tilt is not None
                and tilt > MAX_TILT)


def unsettled(s: dict) -> bool:
    """Whether a trip that walks on (``recovered`` under the walk-on rule, whatever its
    tilt) never settles: no steady gait within the time budget (``steps_to_steady_gait``
    None) or a heading more than ``HEADING_LIMIT_DEG`` from the walk before
    (``walk_on_heading_deg``). False for a fall and under the 1 s rule (no walk on)."""
    if not s["recovered"] or s.get("recovery") != "walk_on":
        return False
    heading = s["walk_on_heading_deg"]
    return bool(s["steps_to_steady_gait"] is None
                or (heading is not None and abs(heading) > HEADING_LIMIT_DEG))


def gait_mismatch(s: dict) -> float:
    """How far a walk on's gait is from the walk before the trip: |v/v₀ − 1| + |T/T₀ − 1|,
    v and T the walk on's speed and step time (``walk_on_speed_m_per_s``,
    ``walk_on_step_s``: its last four steps), v₀ the speed and T₀ half the stride before
    the trip (``walking_stride_s``); 1 when any is missing."""
    v, step_s = s.get("walk_on_speed_m_per_s"), s.get("walk_on_step_s")
    stride = s.get("walking_stride_s")
    if not (v and step_s and stride):
        return 1.0
    return abs(v / s["speed_m_per_s"] - 1.0) + abs(step_s / (stride / 2.0) - 1.0)


def gait_bonus(s: dict) -> float:
    """1 for a walk on at the speed and step time of the walk before the trip, falling
    linearly to 0 at a ``gait_mismatch`` of ``GAIT_SCALE``."""
    return max(0.0, 1.0 - gait_mismatch(s) / GAIT_SCALE)


def flight_score(s: dict) -> int:
    """+1 for a flight phase where people take one, −1 for one where they keep double
    support, else 0 (``stumble.validate.people_fly``: SCA 2009 Table 1, the windows and
    speeds of ``stumble validate``'s flight rows)."""
    from stumble.validate import people_fly

    if s.get("variant") != "flight":
        return 0
    fly = people_fly(s["speed_m_per_s"], s.get("strategy"), s["swing_fraction"])
    return 0 if fly is None else 1 if fly else -1


def push_off_excess(s: dict, f: float, mech: str, body: list) -> float:
    """How far a trip's support limb pushes off beyond people's (``--push-off``): the
    sum over hip extension and knee flexion of max(0, peak/(1.5·mean) − 1), the peaks in
    the first 300 ms (N·m) against Pijnappels et al. 2005's means (52 and 54 N·m;
    ``stumble.validate.PUSH_OFF_NM``, ``PUSH_OFF_FACTOR``); 0 for a trip other than
    validate's nine (the reference body's obstacle trips at 0.25-0.45 of swing). The
    knee's term counts ``KNEE_WEIGHT`` times (``--push-off-knee``; 1 by default)."""
    from stumble.validate import PUSH_OFF_FACTOR, PUSH_OFF_MECHANISM, PUSH_OFF_NM, PUSH_OFF_SWING

    lo, hi = PUSH_OFF_SWING
    if body or mech != PUSH_OFF_MECHANISM or not lo - 1e-9 <= f <= hi + 1e-9:
        return 0.0
    pk = s.get("support_peak_moments_nm") or {}
    out = 0.0
    for name, mean in PUSH_OFF_NM:
        if name != "ankle_plantarflexion" and pk.get(name) is not None:
            weight = KNEE_WEIGHT if name.startswith("knee") else 1.0
            out += weight * max(0.0, pk[name] / (PUSH_OFF_FACTOR * mean) - 1.0)
    return out


def trip_counts(x: dict, i: int) -> tuple[bool, float, float, int, float, bool, bool]:
    """Whether ``GRID[i]`` recovers under ``x`` (``counts``), the time it survived, its
    walk on's ``gait_bonus``, its ``flight_score``, its ``push_off_excess``, whether it
    walks on past ``MAX_TILT`` (``over_tilt``) and whether its walk on is ``unsettled``."""
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    f, v, mech, *body = GRID[i]
    walk_on = ({"recovery": "step"} if WALK_ON_S is None else
               {"recovery": "walk_on", "duration_after_trip_s": WALK_ON_S})
    if body:  # (height m, mass kg, sex): a grid point of another body
        walk_on.update(height_m=body[0], mass_kg=body[1], sex=body[2])
    s = simulate_trip(Scenario(swing_fraction=f, speed_m_per_s=v, mechanism=mech,
                               strength_model=STRENGTH, **walk_on),
                      params=params_from(x)).summary
    return (counts(s), s["sim_time_s"] if not s["fell"] else (s["fall_time_s"] or 0.0),
            gait_bonus(s), flight_score(s), push_off_excess(s, f, mech, body), over_tilt(s),
            unsettled(s))


# --only lowering: the trips the searched targets act on (those the start sends to the
# lowering strategy; no target of ``LOWERING`` is used by an elevating trip), and the
# score of the others, run once with the start's values (``fixed_part``); None: all
ACTIVE = None
FIXED = (0, 0.0, 0, 0.0, 0, 0.0, 0, 0)


def score_of(x: dict, indices) -> tuple[int, float, int, float, int, float, int, int]:
    """(recoveries, total time survived, recoveries among the first 48, the recovered
    trips' summed ``gait_bonus`` and ``flight_score``, every trip's summed
    ``push_off_excess``, the walks on past ``MAX_TILT``, the ``unsettled`` walks on) of
    GRID[indices]."""
    rec, survived, rec_grid, gait, flight, push, over, loose = 0, 0.0, 0, 0.0, 0, 0.0, 0, 0
    for i in indices:
        ok, t, m, fl, po, ov, un = trip_counts(x, i)
        push += po
        over += int(ov)
        loose += int(un)
        rec += int(ok)
        rec_grid += int(ok and i < FLOOR_N)
        survived += t
        gait += m if ok else 0.0
        flight += fl if ok else 0
    return rec, survived, rec_grid, gait, flight, push, over, loose


def evaluate(x: dict) -> tuple[int, float, int, float, int, float, int, int]:
    """``score_of`` over the grid: with ``--only lowering`` its lowering trips run and the
    others' ``FIXED`` score is added (the same figures as running them: they do not use
    the searched targets)."""
    if ACTIVE is None:
        return score_of(x, range(len(GRID)))
    return tuple(a + b for a, b in zip(score_of(x, ACTIVE), FIXED, strict=True))


def fixed_part(base: dict, ex=None) -> tuple[list[int], tuple]:
    """--only lowering: the indices of the trips the start sends to the lowering strategy,
    and the score of the rest under the start's values (run once, in ``ex`` if given)."""
    p = params_from(base)
    active = [i for i, (f, *_rest) in enumerate(GRID) if p.strategy_for(f) == "lowering"]
    rest = [i for i in range(len(GRID)) if i not in set(active)]
    half = (len(rest) + 1) // 2
    parts = ([ex.submit(score_of, base, rest[:half]), ex.submit(score_of, base, rest[half:])]
             if ex else None)
    a, b = ([q.result() for q in parts] if parts else
            (score_of(base, rest), (0, 0.0, 0, 0.0, 0, 0.0, 0, 0)))
    return active, tuple(p + q for p, q in zip(a, b, strict=True))


def penalised(score: tuple) -> tuple[float, float]:
    """(recoveries less the grid floor's penalty plus ``GAIT_WEIGHT`` times the recovered
    trips' summed ``gait_bonus`` and ``FLIGHT_WEIGHT`` times their ``flight_score``, less
    ``PUSH_WEIGHT`` times the summed ``push_off_excess``, ``OVER_TILT_WEIGHT`` times
    the walks on past ``MAX_TILT`` and ``UNSETTLED_WEIGHT`` times the ``unsettled`` walks
    on; time survived): compared as a tuple; without ``--grid-floor``, ``--walk-on-gait``,
    ``--flight``, ``--push-off``, ``--over-tilt`` and ``--unsettled`` the plain
    (recoveries, time survived). ``BODIES_FLOOR`` penalises the body trips (those
    after the first 48) recovered below it as the grid floor does the grid's."""
    rec, survived, rec_grid, gait, flight, push, over, loose = score
    short = 0 if GRID_FLOOR is None else max(0, GRID_FLOOR - rec_grid)
    if BODIES_FLOOR is not None:
        short += max(0, BODIES_FLOOR - (rec - rec_grid))
    return (rec - FLOOR_PENALTY * short + GAIT_WEIGHT * gait + FLIGHT_WEIGHT * flight
            - PUSH_WEIGHT * push - OVER_TILT_WEIGHT * over - UNSETTLED_WEIGHT * loose, survived)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--candidates", type=int, default=48)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--grid", choices=("small", "full", "lowering", "full+bodies"),
                    default="small", help="full+bodies: the full grid and the six bodies' "
                    "96 trips at 1.2 m/s")
    ap.add_argument("--only", choices=ONLY, default="all",
                    help="search only the lowering strategy's targets, or those and its "
                         "Fall's offsets at fast walking (lowering_fast: LOWERING_FAST), or "
                         "those and its flight's (lowering_flight: LOWERING_FLIGHT), or only "
                         "the walk on's (WALK_ON and the reaching leg's; others stay as they "
                         "start), or all the targets and the walk on's together "
                         "(all+walk_on)")
    ap.add_argument("--walk-on-gait", type=float, default=None, metavar="W",
                    help="with --walk-on: each recovered trip adds W times its gait bonus, "
                    "1 - m/0.4 (0 at least), m = |v/v0 - 1| + |T/T0 - 1| of the walk on's "
                    "last steps against the walk before the trip")
    ap.add_argument("--flight", type=float, default=None, metavar="W",
                    help="each recovered trip with a flight phase adds W where people take "
                    "one (1.4 m/s, elevating at 0.05-0.3 of swing, lowering at 0.55-0.75; "
                    "seed 000 Table 1) and loses W at 1.0 m/s (people: double support)")
    ap.add_argument("--around", metavar="FILE|JSON",
                    help="search locally: Gaussian steps (15 %% of each range) around these "
                    "values: a parameter file (as --out writes it; its settings too) "
                    "or JSON text, a parameter file's or an object of "
                    "SPACE names (default: uniform over the ranges)")
    ap.add_argument("--method", choices=("random", "cma"), default="random")
    ap.add_argument("--generations", type=int, default=20, help="cma: generations")
    ap.add_argument("--popsize", type=int, default=12, help="cma: candidates per generation")
    ap.add_argument("--sigma", type=float, default=0.12,
                    help="cma: initial step, as a fraction of each range (default 0.12; "
                    "smaller to refine tuned values)")
    ap.add_argument("--out", default=None, metavar="FILE",
                    help="cma: the best so far, as JSON, rewritten every generation")
    ap.add_argument("--strength", choices=("anderson2007", "fixed"), default="fixed",
                    help="the servos' torque limits (Scenario.strength_model)")
    ap.add_argument("--walk-on", type=float, default=None, metavar="S",
                    help="recovered = still walking S s after the trip (Scenario recovery "
                    "walk_on) instead of 1 s after the recovery step")
    ap.add_argument("--attitude-damping", choices=("joint", "pelvis"), default=None,
                    help="FSMParams.attitude_damping of every candidate (default: the "
                    "--around file's settings, else joint; one differing from the file's "
                    "is refused)")
    ap.add_argument("--gains", action="store_true",
                    help="search the servo gains too (GAINS) as well as the targets")
    ap.add_argument("--flight-targets", action="store_true",
                    help="search both Flight tables' targets too (ELEV_FLIGHT and the "
                    "lowering's fl_low_*)")
    ap.add_argument("--flight-from-fall", action="store_true", default=None,
                    help="every candidate enters Flight when its support foot leaves the "
                    "floor in Fall (FSMParams.flight_from_fall; a setting of the file)")
    ap.add_argument("--lateral", action="store_true",
                    help="search the frontal plane's values too (LATERAL: the coronal foot "
                    "placement's gains, the hips' out-of-plane gains)")
    ap.add_argument("--trunk-attitude", type=float, default=None, metavar="K",
                    help="FSMParams.trunk_attitude of every candidate (default: the --around "
                    "file's settings, else 0: off; one differing from the file's is refused)")
    ap.add_argument("--max-tilt", type=float, default=None, metavar="DEG",
                    help="a recovery counts only if the trunk is within DEG of vertical at "
                    "recovery-foot contact (people: 23-26, van den Bogert et al. 2002)")
    for option, field, servo in (("--rec-hip-cap", "push_off_rec_hip_limit_nm",
                                  "the recovery hip's servo"),
                                 ("--sup-hip-cap", "push_off_hip_limit_nm",
                                  "the support hip's attitude servo"),
                                 ("--sup-knee-cap", "push_off_sup_knee_limit_nm",
                                  "the support knee's servo")):
        ap.add_argument(option, type=float, default=None, metavar="NM",
                        help=f"FSMParams.{field} of every candidate: {servo} capped at NM "
                        "N·m in the push-off (default: the --around file's settings, else "
                        "none; one differing is refused)")
    ap.add_argument("--push-off", type=float, default=None, metavar="W",
                    help="with --grid full or full+bodies: the objective loses W per unit "
                    "of the nine mid-swing obstacle trips' push-off excess over 1.5 x "
                    "Pijnappels et al. 2005 (hip 52, knee 54 N·m)")
    ap.add_argument("--push-off-knee", type=float, default=None, metavar="K",
                    help="with --push-off: the knee's excess counts K times (default 1)")
    ap.add_argument("--bodies-floor", type=int, default=None, metavar="N",
                    help="with --grid full+bodies: penalise the objective by 2 per body trip "
                    f"(of the {len(BODY_GRID)}) recovered below N")
    ap.add_argument("--grid-floor", type=int, default=None, metavar="N",
                    help="penalise the objective by 2 per trip of the first 48 (the full "
                    "grid, before full+bodies' bodies) recovered below N")
    ap.add_argument("--over-tilt", type=float, default=None, metavar="W",
                    help="with --max-tilt: the objective loses W per trip that walks on with "
                    "the trunk past DEG at recovery-foot contact (such a trip already does "
                    "not count as recovered; this also pushes the search away from it)")
    ap.add_argument("--unsettled", type=float, default=None, metavar="W",
                    help="with --walk-on: the objective loses W per trip that walks on and "
                    "never reaches a steady gait or turns more than "
                    f"{HEADING_LIMIT_DEG:g} deg from the walk before")
    args = ap.parse_args()
    if args.trunk_attitude is not None and not (np.isfinite(args.trunk_attitude)
                                                and args.trunk_attitude >= 0):
        ap.error(f"--trunk-attitude must be a number >= 0, got {args.trunk_attitude}")
    from stumble.control.fsm_params import check_setting
    from stumble.errors import InputError

    around, file_settings = {}, {}
    try:
        if args.around:
            around, file_settings = read_around(args.around)
        trunk_attitude = setting_of("trunk_attitude", args.trunk_attitude, file_settings)
        attitude_damping = setting_of("attitude_damping", args.attitude_damping,
                                      file_settings)
        rec_hip_cap = setting_of("push_off_rec_hip_limit_nm", args.rec_hip_cap, file_settings,
                                 "--rec-hip-cap")
        sup_hip_cap = setting_of("push_off_hip_limit_nm", args.sup_hip_cap, file_settings,
                                 "--sup-hip-cap")
        sup_knee_cap = setting_of("push_off_sup_knee_limit_nm", args.sup_knee_cap,
                                  file_settings, "--sup-knee-cap")
        flight_from_fall = setting_of("flight_from_fall", args.flight_from_fall,
                                      file_settings)
        for option, name, cap in (("--rec-hip-cap", "push_off_rec_hip_limit_nm", rec_hip_cap),
                                  ("--sup-hip-cap", "push_off_hip_limit_nm", sup_hip_cap),
                                  ("--sup-knee-cap", "push_off_sup_knee_limit_nm",
                                   sup_knee_cap)):
            check_setting(name, cap, option)  # as a parameter file's settings
    except InputError as e:
        ap.error(str(e))
    if args.max_tilt is not None and not (np.isfinite(args.max_tilt) and args.max_tilt > 0):
        ap.error(f"--max-tilt must be a number of degrees > 0, got {args.max_tilt}")
    if args.over_tilt is not None and (args.max_tilt is None or not (
            np.isfinite(args.over_tilt) and args.over_tilt > 0)):
        ap.error("--over-tilt needs --max-tilt DEG and a weight > 0")
    if args.unsettled is not None and (args.walk_on is None or not (
            np.isfinite(args.unsettled) and args.unsettled > 0)):
        ap.error("--unsettled needs --walk-on S and a weight > 0")
    if args.walk_on_gait is not None and (args.walk_on is None or not (
            np.isfinite(args.walk_on_gait) and args.walk_on_gait > 0)):
        ap.error("--walk-on-gait needs --walk-on S and a weight > 0")
    if args.flight is not None and not (np.isfinite(args.flight) and args.flight > 0):
        ap.error(f"--flight must be a weight > 0, got {args.flight}")
    if args.push_off is not None and (args.grid not in ("full", "full+bodies") or not (
            np.isfinite(args.push_off) and args.push_off > 0)):
        ap.error("--push-off needs --grid full (or full+bodies) and a weight > 0")
    if args.push_off_knee is not None and (args.push_off is None or not (
            np.isfinite(args.push_off_knee) and args.push_off_knee >= 0)):
        ap.error("--push-off-knee needs --push-off W and a weight >= 0")
    if args.bodies_floor is not None and (args.grid != "full+bodies"
                                          or not 0 <= args.bodies_floor <= len(BODY_GRID)):
        ap.error(f"--bodies-floor needs --grid full+bodies and 0-{len(BODY_GRID)} trips")
    if args.grid_floor is not None:
        if args.grid not in ("full", "full+bodies"):
            ap.error("--grid-floor counts the full grid's 48 trips: give --grid full or "
                     "full+bodies")
        if not 0 <= args.grid_floor <= FLOOR_N:
            ap.error(f"--grid-floor must be 0-{FLOOR_N}, got {args.grid_floor}")
    global GRID, STRENGTH, WALK_ON_S, ATTITUDE_DAMPING, TRUNK_ATTITUDE, MAX_TILT, GRID_FLOOR
    global ACTIVE, FIXED, GAIT_WEIGHT, FLIGHT_WEIGHT, REC_HIP_CAP, SUP_HIP_CAP, PUSH_WEIGHT
    global KNEE_WEIGHT, BODIES_FLOOR, SUP_KNEE_CAP, FLIGHT_FROM_FALL
    SUP_KNEE_CAP, FLIGHT_FROM_FALL = sup_knee_cap, flight_from_fall
    KNEE_WEIGHT = 1.0 if args.push_off_knee is None else args.push_off_knee
    BODIES_FLOOR = args.bodies_floor
    global OVER_TILT_WEIGHT, UNSETTLED_WEIGHT
    OVER_TILT_WEIGHT, UNSETTLED_WEIGHT = args.over_tilt or 0.0, args.unsettled or 0.0
    GAIT_WEIGHT, FLIGHT_WEIGHT = args.walk_on_gait or 0.0, args.flight or 0.0
    REC_HIP_CAP, SUP_HIP_CAP, PUSH_WEIGHT = rec_hip_cap, sup_hip_cap, args.push_off or 0.0
    GRID = {"small": GRID, "full": FULL_GRID, "lowering": LOWERING_GRID,
            "full+bodies": FULL_GRID + BODY_GRID}[args.grid]
    ATTITUDE_DAMPING = attitude_damping
    TRUNK_ATTITUDE, MAX_TILT, GRID_FLOOR = trunk_attitude, args.max_tilt, args.grid_floor
    STRENGTH, WALK_ON_S = args.strength, args.walk_on
    space = search_space(args.only, args.gains, args.lateral, args.flight_targets)
    rng = np.random.default_rng(args.seed)
    from stumble.control.fsm_params import FSMParams

    default = FSMParams()
    base = default.values()
    base.update(around)
    if args.only in ("lowering", "lowering_fast", "lowering_flight"):  # the other trips
        # do not use the searched targets: they run once
        t0 = time.time()
        if args.workers > 1:
            with ProcessPoolExecutor(2, initializer=_worker_init,
                                     initargs=_init_args()) as pool:
                ACTIVE, FIXED = fixed_part(base, pool)
        else:
            ACTIVE, FIXED = fixed_part(base)
        print(f"--only lowering: {len(ACTIVE)} of {len(GRID)} trips searched; the other "
              f"{len(GRID) - len(ACTIVE)} recover {FIXED[0]} (grid {FIXED[2]}) with the "
              f"start's values, run once ({time.time() - t0:.0f} s)", flush=True)
    if args.method == "cma":
        _cma(args, base, space)
        return
    if args.around:
        cands = [base] + [{**base, **{k: float(np.clip(base[k] + rng.normal(0, 0.15 * (hi - lo)),
                                                       lo, hi))
                                      for k, (_p, lo, hi) in space.items()}}
                          for _ in range(args.candidates)]
    else:
        cands = [base] + [{**base, **{k: float(rng.uniform(lo, hi))
                                      for k, (_p, lo, hi) in space.items()}}
                          for _ in range(args.candidates)]
    t0 = time.time()
    best = None
    # one worker: evaluate in this process (no pool), for a machine shared with others
    ex = ProcessPoolExecutor(args.workers, initializer=_worker_init, initargs=_init_args()
                             ) if args.workers > 1 else None
    scores = ex.map(evaluate, cands) if ex else map(evaluate, cands)
    try:
        for i, (x, score) in enumerate(zip(cands, scores, strict=True)):
            if best is None or penalised(score) > penalised(best[1]):
                best = (x, score)
            print(f"{i:3d} recovered {score[0]:2d}/{len(GRID)} survived {score[1]:6.2f} s "
                  f"grid {score[2]} best {best[1][0]} ({time.time() - t0:.0f} s)", flush=True)
    finally:
        if ex:
            ex.shutdown()
    print(json.dumps({"recovered": best[1][0], "of": len(GRID), "grid_recovered": best[1][2],
                      "params": best[0], "settings": settings()}, indent=1))


def _init_args() -> tuple:
    """The module's settings, for ``_worker_init`` in a worker process."""
    return (STRENGTH, GRID, WALK_ON_S, ATTITUDE_DAMPING, TRUNK_ATTITUDE, MAX_TILT, ACTIVE,
            FIXED, GAIT_WEIGHT, FLIGHT_WEIGHT, REC_HIP_CAP, PUSH_WEIGHT, SUP_HIP_CAP,
            KNEE_WEIGHT, SUP_KNEE_CAP, FLIGHT_FROM_FALL)


def _worker_init(strength: str, grid: list, walk_on_s: float | None,
                 attitude_damping: str = "joint", trunk_attitude: float = 0.0,
                 max_tilt: float | None = None, active=None,
                 fixed: tuple = (0, 0.0, 0, 0.0, 0, 0.0, 0, 0), gait_weight: float = 0.0,
                 flight_weight: float = 0.0, rec_hip_cap: float | None = None,
                 push_weight: float = 0.0, sup_hip_cap: float | None = None,
                 knee_weight: float = 1.0, sup_knee_cap: float | None = None,
                 flight_from_fall: bool = False) -> None:
    global STRENGTH, GRID, WALK_ON_S, ATTITUDE_DAMPING, TRUNK_ATTITUDE, MAX_TILT
    global ACTIVE, FIXED, GAIT_WEIGHT, FLIGHT_WEIGHT, REC_HIP_CAP, PUSH_WEIGHT, SUP_HIP_CAP
    global KNEE_WEIGHT, SUP_KNEE_CAP, FLIGHT_FROM_FALL
    KNEE_WEIGHT, SUP_KNEE_CAP, FLIGHT_FROM_FALL = knee_weight, sup_knee_cap, flight_from_fall
    STRENGTH, GRID, WALK_ON_S, ATTITUDE_DAMPING = strength, grid, walk_on_s, attitude_damping
    TRUNK_ATTITUDE, MAX_TILT, ACTIVE, FIXED = trunk_attitude, max_tilt, active, fixed
    GAIT_WEIGHT, FLIGHT_WEIGHT = gait_weight, flight_weight
    REC_HIP_CAP, PUSH_WEIGHT, SUP_HIP_CAP = rec_hip_cap, push_weight, sup_hip_cap


def _gait(score: tuple) -> str:
    """The recovered trips' summed gait bonus and flight score, the push-off excess, the
    walks on past the tilt and those unsettled, for the log (each with its option)."""
    return ((f", gait {score[3]:.1f}" if GAIT_WEIGHT else "")
            + (f", flight {score[4]:+d}" if FLIGHT_WEIGHT else "")
            + (f", push-off excess {score[5]:.2f}" if PUSH_WEIGHT else "")
            + (f", past the tilt {score[6]}" if OVER_TILT_WEIGHT else "")
            + (f", unsettled {score[7]}" if UNSETTLED_WEIGHT else ""))


def generations_path(out: str) -> str:
    """Where ``--out FILE`` puts every generation's best: FILE's name with
    ``.generations.jsonl`` for its suffix (one JSON record a line)."""
    from pathlib import Path

    return str(Path(out).with_suffix(".generations.jsonl"))


def _cma(args, base: dict, space: dict) -> None:
    """CMA-ES over ``space`` (each name scaled to its range), from ``base``."""
    from cmaes import CMA

    names = list(space)
    lo = np.array([space[k][1] for k in names])
    hi = np.array([space[k][2] for k in names])
    x0 = np.clip((np.array([base[k] for k in names]) - lo) / (hi - lo), 0.0, 1.0)
    opt = CMA(mean=x0, sigma=args.sigma, bounds=np.array([[0.0, 1.0]] * len(names)),
              seed=args.seed, population_size=args.popsize)

    def point(u: np.ndarray) -> dict:
        return {**base, **{k: float(v) for k, v in zip(names, lo + u * (hi - lo), strict=True)}}

    ex = ProcessPoolExecutor(args.workers, initializer=_worker_init, initargs=_init_args()
                             ) if args.workers > 1 else None
    t0, best = time.time(), None
    span = (WALK_ON_S or 3.0) * len(GRID)  # the grid's time budget
    try:
        first = evaluate(base) if ex is None else ex.submit(evaluate, base).result()
        best, best_gen = (base, first), -1
        print(f"start recovered {first[0]}/{len(GRID)} survived {first[1]:.1f} s "
              f"grid {first[2]}{_gait(first)}", flush=True)
        for g in range(args.generations):
            us = [opt.ask() for _ in range(opt.population_size)]
            xs = [point(u) for u in us]
            scores = list(ex.map(evaluate, xs) if ex else map(evaluate, xs))
            pens = [penalised(sc) for sc in scores]
            opt.tell([(u, -(r + sv / span)) for u, (r, sv) in zip(us, pens, strict=True)])
            for x, sc in zip(xs, scores, strict=True):
                if penalised(sc) > penalised(best[1]):
                    best, best_gen = (x, sc), g
            i_top = pens.index(max(pens))
            top = scores[i_top]
            print(f"gen {g:2d} best of gen {top[0]}/{len(GRID)} (grid {top[2]}{_gait(top)}) "
                  f"overall {best[1][0]} (grid {best[1][2]}{_gait(best[1])}) "
                  f"({time.time() - t0:.0f} s)", flush=True)
            if args.out:
                argv = __import__("sys").argv[1:]
                with open(args.out, "w") as fh:
                    json.dump(out_record(best, best_gen, argv), fh, indent=1)
                # every generation's best too, as it goes: the objective weighs the
                # issue's criteria only roughly, so a generation's best may be the one
                # to keep (``--out`` holds the best by the objective)
                with open(generations_path(args.out), "a") as fh:
                    fh.write(json.dumps(out_record((xs[i_top], top), g, argv)) + "\n")
    finally:
        if ex:
            ex.shutdown()
    print(json.dumps({"recovered": best[1][0], "of": len(GRID), "grid_recovered": best[1][2],
                      "params": best[0], "settings": settings()}, indent=1))


if __name__ == "__main__":
    main()
