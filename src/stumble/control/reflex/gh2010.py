"""Geyer & Herr 2010's muscle-reflex walker on the planar musculoskeletal body.

Geyer & Herr, *A muscle-reflex model that encodes principles of legged mechanics produces
human walking dynamics and muscle activities*, IEEE TNSRE 18:263 (2010): each leg is in
stance or swing by its ground contact, and each muscle's excitation is a prestimulation
plus reflexes on delayed muscle force (F, in F_max), fibre length (l, in l_opt), joint
angle and trunk lean. The laws (``excitations``):

stance
  SOL = S0 + G_SOL·F_SOL                               (ankle delay)
  TA  = S0 + G_TA·[l_TA − l_off,TA]+ − G_SOL,TA·F_SOL  (ankle)
  GAS = S0 + G_GAS·F_GAS                               (ankle)
  VAS = S0,VAS + G_VAS·F_VAS − k_φ·[φ_off − φ]+ while the knee extends   (knee; φ the
        knee flexion: no overextension)
  GLU, HAM = S0,BAL + [k_p(θ − θ_ref) + k_d·θ̇]+ · share;  HFL = S0,BAL + [−(…)]+ · share
        (hip; θ the trunk's forward lean, share the leg's part of the body's load)
  trailing leg in double support: GLU −= k_bw·F_other/mg, HFL += k_bw·F_other/mg
swing
  HFL = S0 + G_HFL·[l_HFL − l_off,HFL]+ − G_HAM,HFL·[l_HAM − l_off,HAM]+ + k_lean(θ − θ_ref)
  GLU = S0 + G_GLU·F_GLU;  HAM = S0 + G_HAM·F_HAM      (hip)
  TA  = S0 + G_TA·[l_TA − l_off,TA]+                    (ankle)
  SOL, GAS, VAS = S0

Delays: 5 ms (hip), 10 ms (knee), 20 ms (ankle), Geyer & Herr 2010. The initial
parameters (``GH2010Params``) are the paper's as tabulated in SCONE's GH2010 controller
(Geijtenbeek, ``ControllerGH2010.scone``); the paper's own table was not read. Our
choices, each a field: the stance/swing switch is the delayed foot load against 10 % of
body weight (SCONE's stance threshold); the lean in the swing HFL law is the delayed
lean, not its value at take-off; the trunk law is rectified and weighted by the leg's
load share; RF, which Geyer & Herr's model does not have, stays at its prestimulation
(without an HFL in the body, RF takes HFL's laws). The shipped, walking parameters come
from a closed-loop optimisation (``stumble.control.reflex.fit_walk``).

All channels are read from MuJoCo sensor rows through ``DelayTaps`` (one signal, several
reflex paths, each its own lag); every delay is at least 5 ms, so the controller fixes
5 ms of excitations at a time and the physics loop steps them natively.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields, replace
from importlib import resources

import numpy as np

from stumble.body.muscles import PRE_ACTIVATION
from stumble.control.reflex.delays import DelayTaps
from stumble.control.reflex.kernels import kernels
from stumble.errors import InputError
from stumble.sim import Context

SIDES = ("r", "l")
DELAY_BY_JOINT_S = {"hip": 0.005, "knee": 0.010, "ankle": 0.020}  # Geyer & Herr 2010
# the joint whose delay each muscle's own reflexes use (Geyer & Herr 2010)
JOINT_OF = {"HAMS": "hip", "GLU": "hip", "HFL": "hip", "RF": "hip", "VAS": "knee",
            "GAS": "ankle", "SOL": "ankle", "TA": "ankle"}
WIRINGS = ("gh2010", "seed003")
# The stumbling corrective reflex, our addition to Geyer & Herr 2010 (off in the paper's
# parameters). Song & Geyer 2017 (Front. Comput. Neurosci. 11:15) found their reflex walker's
# responses to whole-body disturbances too weak and proposed "location-specific cutaneous
# reflexes"; a touch on the front of the swing foot is such a reflex, the stumbling
# corrective response (Schillings et al. 2000; Eng et al. 1994): the tripped leg's
# hamstrings (BF at 64 ms, Eng et al. 1994), TA and hip flexor, and the support leg's
# plantarflexors and gluteus (Pijnappels et al. 2005). One pathway at every phase: which
# strategy follows is left to the mechanics. The touch is the foot's contact with the
# obstacle (the only thing that touches a foot but the floor), read through a delay tap.
#
# ``scr_phase`` (our choice, a parameter): ``any``, the same response at every phase of
# swing (which strategy follows is then left to the mechanics alone), or ``foot``: the
# tripped leg's response reverses with the phase of its swing, as human cutaneous
# reflexes do (phase-dependent reflex reversal, Zehr & Stein 1999, Prog. Neurobiol.
# 58:185; Schillings et al. 2000): with the tripped foot behind the other (early swing)
# the flexion set above, ahead of it (late swing) the extension set, RF and SOL (Eng et
# al. 1994, seed 003 §IV.A: lowering by RF and SOL 50-100 ms after the trip), GLU and
# HAMS (the hip's extensors, which pull the foot back and down).
# The phase is where the feet were at the touch's onset, sensed with the touch (the hip
# delay's foot positions, read at the touch's latency) and held while it lasts: no
# strategy is chosen, the response is one law of the leg's state when it is tripped.
# (The knee's motion was tried first: in late swing the struck knee rebounds from full
# extension, and reads as flexing.)
SCR_GAINS = ("g_scr_ham", "g_scr_ta", "g_scr_flex", "g_scr_sol", "g_scr_gas", "g_scr_glu",
             "g_scr_vas", "g_scr_ext_rf", "g_scr_ext_sol", "g_scr_ext_glu", "g_scr_ext_ham")
SCR_PHASES = ("any", "foot")
# The crossing step after a touch (our addition, a parameter set; zero, off, in the paper's
# and the shipped gains). A person who has struck an obstacle knows it is there, and each
# leg's next step crosses it with the exaggerated hip and knee flexion and dorsiflexion of
# a deliberate step over an obstacle (Chou & Draganich 1997, J Biomech 30:331: the trailing
# limb's knee flexes further; the gains are ours, fitted). Reflexes alone
# step over nothing on purpose: after a lowering the other leg must cross the box, and
# after either strategy the leg still behind it must. As a law: a sensed touch arms both
# legs and marks where the obstacle is (``cross_ahead_m`` ahead of the touched foot's
# ankle at the touch's onset, sensed with the touch: the toe and the box are ahead of the
# ankle); when a foot lands on the floor (its delayed load rises past
# ``stance_load``), the other leg, if armed, is disarmed and, if its foot is still behind
# the mark (it has the obstacle to cross), for ``cross_hold_s`` gains ``g_cross_*`` on
# its hip flexor, HAMS (knee flexion), TA and GAS (push-off, knee flexion). After an
# elevating step the tripped foot lands beyond the mark and the other leg crosses; after
# a lowering both do, the other leg first. No strategy is chosen: whichever foot lands
# first launches the other's step.
CROSS_GAINS = ("g_cross_flex", "g_cross_ham", "g_cross_ta", "g_cross_gas")
# the parameters of the reflexes a touch triggers: before the first touch they add
# nothing (``GH2010Controller.retouch``)
TOUCH_FIELDS = (*SCR_GAINS, *CROSS_GAINS, "scr_hold_s", "scr_vas_after_s", "scr_ahead_m",
                "cross_hold_s", "cross_ahead_m")
# swing-leg placement (GH2010Params.k_place and after; off in the paper and the shipped
# fits): fitted only with ``--placement``
PLACE_FIELDS = ("k_place", "place_a0", "place_cd", "place_cv")
# What a leg's load is (``load_from``; our choice, a parameter): ``floor``, the floor's
# force on the foot alone (the paper's ground contact, and every shipped fit's), or
# ``any``, the floor's and the obstacle's: a person feels weight on the sole whatever it
# stands on (plantar mechanoreceptors, the extensors' tendon organs), and a foot that
# comes to rest on the box after a trip carries the body (up to 1.4 body weights, 0.65
# of swing at 1.2 m/s) while a floor-only load leaves that leg in swing, its stance
# reflexes off, so that the leg folds under the body.
LOAD_SOURCES = ("floor", "any")
# optimised parameters shipped in stumble/control/reflex/data/, per wiring: for gh2010
# (the default since 2026-12-05, third session) the third 2 ms touch stage by seed 3
# (``knee-2ms-dense-wide-s3``: 33 of the 45 trips and 21 of the held-out 28 recovered,
# falls rising with the delay; run at its 2 ms step); the network's expert for seed003
SHIPPED = {"gh2010": "gh2010_knee_2ms_dense_wide_s3.json", "seed003": "gh2010_seed003.json"}
# the walking fit the shipped GH2010 set's touch stage started from (``--params
# knee-walk``), where a trip stage without ``--params`` starts
SHIPPED_WALKING: dict[str, str] = {"gh2010": "gh2010_knee_walk.json"}
# the walking fit the network's expert (seed003 wiring) was fitted from: the first walking
# fit, pinned so that the expert's fit starts where it did whatever the default is (its
# recorded command does not reproduce the shipped expert: docs/gh2010.md "Reproducing the
# shipped fits")
SEED003_START = "gh2010_walk.json"
# every shipped GH2010 parameter set by the name ``--params`` takes: the first walking fit
# (``walk``) and the trip fit on it (``trip``, the default until 2026-12-04); the pushed
# walking fit (``reflex fit --pushes``, ``pushed-walk``) and the touch stages fitted on it
# (``pushed``, the default for part of 2026-12-04); the pushed walking fit refitted with
# the knee term (``--knee-weight 5``, ``knee-walk``) and the touch stage on it (``knee``,
# the default from 2026-12-04 to 2026-12-05); and a touch stage on it with the response
# by the foot's phase (``--scr-phase foot``, ``knee-foot``: the first shipped set that
# recovers by lowering)
NAMED = {"walk": SEED003_START, "trip": "gh2010_trip.json",
         "pushed-walk": "gh2010_pushed_walk.json", "pushed": "gh2010_pushed.json",
         "knee-walk": SHIPPED_WALKING["gh2010"], "knee": "gh2010_knee.json",
         "knee-foot": "gh2010_knee_foot.json",
         # the touch stage of ``knee`` refitted at a 2 ms step (``--timestep 0.002``): runs
         # at 2 ms, twice as fast (docs/speed.md "Speed"; since 2026-12-04, later that day)
         "knee-2ms": "gh2010_knee_2ms.json",
         # a second touch stage on ``knee-2ms``, on the dense thirty (1.1 and 1.3 m/s):
         # as many of the 45 recover, more held-out trips (docs/gh2010.md "Geyer & Herr 2010";
         # since 2026-12-05)
         "knee-2ms-dense": "gh2010_knee_2ms_dense.json",
         # and a third, on ``knee-2ms-dense``, on the wide twelve: 31 of the 45, the
         # falls rising with the delay (since 2026-12-05; the default that day, second
         # and third sessions)
         "knee-2ms-dense-wide": "gh2010_knee_2ms_dense_wide.json",
         # the same command by seed 3, the best of seeds 0-4 on the 45: 33 of them (the
         # issue's 70 %), 21 of the held-out 28 as seed 0's (the default since
         # 2026-12-05, third session)
         "knee-2ms-dense-wide-s3": SHIPPED["gh2010"],
         # seed003-wired: the placing expert of the ``placement`` network, reproducible
         # (docs/reflex-network.md; since 2026-12-04, later that day)
         "expert-placement": "gh2010_seed003_placement.json",
         # a touch stage on it (``reflex fit --wiring seed003 --trips --params
         # expert-placement``): the first seed003-wired set that recovers trips, 25 of the
         # 45 (docs/reflex-fits.md; since 2026-12-05, third session)
         "expert-touch": "gh2010_seed003_touch.json"}


@dataclass(frozen=True)
class GH2010Params:
    """Gains of the Geyer & Herr 2010 reflexes (F in F_max, l in l_opt, angles in rad).

    Defaults: Geyer & Herr 2010 as tabulated in SCONE's ControllerGH2010 (Geijtenbeek).
    """

    s0: float = PRE_ACTIVATION  # prestimulation of every muscle
    s0_vas: float = 0.09  # VAS stance prestimulation
    s0_bal: float = 0.05  # stance hip muscles' prestimulation (trunk balance)
    g_sol: float = 1.2  # SOL F+ (stance)
    g_sol_ta: float = 0.3  # SOL F- onto TA (stance)
    g_ta: float = 1.1  # TA L+ (stance and swing)
    l_off_ta: float = 0.71
    g_gas: float = 1.1  # GAS F+ (stance)
    g_vas: float = 1.15  # VAS F+ (stance)
    k_phi: float = 2.0  # knee overextension inhibition of VAS, per rad
    phi_off: float = np.radians(10.0)  # knee flexion below which it acts
    kp_trunk: float = 1.91  # per rad
    kd_trunk: float = 0.2  # s/rad
    lean_ref: float = 0.105  # rad, forward
    k_bw: float = 1.2  # double support: per body weight of the other leg's load
    g_hfl: float = 0.35  # HFL L+ (swing)
    l_off_hfl: float = 0.60
    g_ham_hfl: float = 4.0  # HAM L- onto HFL (swing)
    l_off_ham: float = 0.85
    k_lean: float = 1.15  # swing HFL on the trunk lean, per rad
    g_ham: float = 0.65  # HAM F+ (swing)
    g_glu: float = 0.4  # GLU F+ (swing)
    stance_load: float = 0.1  # stance: delayed foot load above this share of body weight
    # the stumbling corrective reflex (``STUMBLE_REFLEX``; not in Geyer & Herr 2010, whose
    # gains are these zeros): a touch on a foot's front, after scr_latency_s, excites for
    # scr_hold_s that leg's HAMS, TA and hip flexor and the other leg's SOL, GAS and GLU
    scr_latency_s: float = 0.065  # s; Eng et al. 1994 (seed 003 §IV.A): BF 64 ms after a trip
    scr_hold_s: float = 0.15  # s, how long one touch's response lasts (our choice)
    g_scr_ham: float = 0.0
    g_scr_ta: float = 0.0
    g_scr_flex: float = 0.0
    g_scr_sol: float = 0.0  # the other (support) leg: Pijnappels et al. 2005
    g_scr_gas: float = 0.0
    g_scr_glu: float = 0.0
    g_scr_vas: float = 0.0  # the tripped leg's knee extensor, scr_vas_after_s later
    scr_vas_after_s: float = 0.1  # s after the flexors' onset (our choice; Eng et al.
    # 1994's lowering response is a knee extensor's, RF, 50-100 ms after the trip)
    # the tripped leg's extension set (``scr_phase`` foot: tripped ahead of the other)
    g_scr_ext_rf: float = 0.0
    g_scr_ext_sol: float = 0.0
    g_scr_ext_glu: float = 0.0
    g_scr_ext_ham: float = 0.0
    scr_phase: str = "any"  # "any" or "foot" (``SCR_PHASES``)
    # ``scr_phase`` foot: the tripped foot counts as ahead of the other (the extension
    # set) when its ankle is more than this in front of the other's at the touch (m; 0,
    # the default, is "ahead"; a negative value also counts a foot a little behind: a
    # walker whose swing ankle passes the other late, as the TA-bounded fits', whose
    # tripped ankle is still 0.16-0.45 m behind the other's at 0.55-0.75 of swing)
    scr_ahead_m: float = 0.0
    # the crossing step after a touch (``CROSS_GAINS``; zero in the paper and the
    # shipped fits): the other leg's flexors when a foot lands after a sensed touch
    g_cross_flex: float = 0.0
    g_cross_ham: float = 0.0
    g_cross_ta: float = 0.0
    g_cross_gas: float = 0.0
    cross_hold_s: float = 0.2  # s, how long a crossing drive lasts (our choice)
    # the obstacle's far side, ahead of the touched foot's ankle at the touch (m; our
    # choice: the toe 0.2 m ahead of the ankle, a 10 cm box; a foot landing beyond it
    # has crossed)
    cross_ahead_m: float = 0.3
    # swing-leg placement (``PLACE_FIELDS``; our addition after Song & Geyer 2015, J Physiol
    # 593:3493, whose swing leg is driven toward a target angle set by the centre of mass;
    # off, k_place 0, in Geyer & Herr 2010 and every shipped fit): on a swing leg ahead of
    # vertical, the flexor gets k_place·[α_tgt − α]+ and GLU k_place·[α − α_tgt]+, α the
    # leg's angle from vertical (pelvis to ankle, forward positive), α_tgt = place_a0 +
    # place_cd·d + place_cv·v, d the centre of mass ahead of the other (stance) ankle, v
    # its forward speed; sensed with the trunk-lean laws' delay. A walking law: it acts
    # from the first step, and a fit that uses it refits the walk (``--placement``)
    k_place: float = 0.0  # per rad
    place_a0: float = 0.35  # rad (the shipped walker's leg at touch-down: 0.32-0.41 rad)
    place_cd: float = 0.0  # rad/m
    place_cv: float = 0.0  # rad per m/s
    delay_scale: float = 1.0  # every delay multiplied by this
    # the delays of the reflexes a touch triggers (the stumbling corrective reflex's
    # latency and holds, the crossing step's hold) multiplied by this too
    # (``Scenario.delays`` response: the response to the trip slower, the walk not)
    response_delay_scale: float = 1.0
    wiring: str = "gh2010"  # "gh2010" or "seed003" (see GH2010Controller)
    load_from: str = "floor"  # "floor" or "any" (``LOAD_SOURCES``)
    # the physics step (s) the gains were fitted at (``reflex fit --timestep``): runs take
    # it unless told a step that divides it (``trip.check_gh2010_timestep``); every set
    # fitted before 2026-12-04's step option was fitted at 1 ms, its files without it
    timestep_s: float = 0.001

    def free(self) -> list[str]:
        """Names of the gains a closed-loop fit may change (not the delays, the wiring)."""
        return [f.name for f in fields(self)
                if f.name not in ("delay_scale", "response_delay_scale", "wiring",
                                  "scr_latency_s", "scr_phase", "load_from", "timestep_s")]

    @property
    def stumble_reflex(self) -> bool:
        """Whether any gain of the stumbling corrective reflex, or of the crossing step
        that follows a touch, is on (either needs the touch sensed)."""
        return any(getattr(self, n) for n in SCR_GAINS + CROSS_GAINS)

    @property
    def crossing(self) -> bool:
        """Whether any gain of the crossing step after a touch is on."""
        return any(getattr(self, n) for n in CROSS_GAINS)

    def vector(self) -> np.ndarray:
        """The free gains as a vector, in ``free()`` order."""
        return np.array([getattr(self, n) for n in self.free()])

    def with_vector(self, x: np.ndarray) -> GH2010Params:
        """A copy with the free gains from ``x``."""
        return replace(self, **{n: float(v) for n, v in zip(self.free(), x, strict=True)})

    def to_json(self) -> dict:
        """Plain numbers and the wiring (for the shipped file and fit reports; the fitted
        step only when not 1 ms, as the files before it; not the response's delay scale,
        a run's setting, ``Scenario.delays``)."""
        return {k: v if isinstance(v, str) else float(v) for k, v in asdict(self).items()
                if (k != "timestep_s" or v != 0.001) and k != "response_delay_scale"}

    @classmethod
    def from_json(cls, obj: dict) -> GH2010Params:
        """Read ``to_json``'s form; InputError naming an unknown or non-finite field."""
        names = {f.name for f in fields(cls)} - {"response_delay_scale"}  # a run's
        bad = sorted(set(obj) - names)
        if bad:
            raise InputError(f"unknown GH2010 parameter(s): {', '.join(bad)}")
        vals = {}
        for k, v in obj.items():
            if k in ("wiring", "scr_phase", "load_from"):
                allowed = {"wiring": WIRINGS, "scr_phase": SCR_PHASES,
                           "load_from": LOAD_SOURCES}[k]
                if v not in allowed:
                    raise InputError(f"GH2010 {k} {v!r} is not one of {', '.join(allowed)}")
                vals[k] = v
                continue
            if not isinstance(v, int | float) or isinstance(v, bool) or not np.isfinite(v):
                raise InputError(f"GH2010 parameter {k} must be a finite number, got {v!r}")
            if k == "timestep_s" and not 0.0002 <= v <= 0.005:
                raise InputError(f"GH2010 timestep_s {v!r} is outside 0.0002-0.005 s")
            if k.endswith("_s") and v < 0:  # latencies, holds, onsets (s)
                raise InputError(f"GH2010 parameter {k} is a time and must be >= 0, got {v!r}")
            lo, hi = file_range(k)
            if not lo <= v <= hi:
                raise InputError(f"GH2010 parameter {k} = {v!r} is outside {lo:g}-{hi:g} "
                                 "(a parameter file's sanity range)")
            vals[k] = float(v)
        return cls(**vals)


# Sanity ranges of a parameter file's values, by the field's kind (ours: wide enough for
# any fit's bounds, fit_walk.GH2010_BOUNDS and GAIN_RANGE times the paper's gains, and
# for hand-made sets; a value outside is a typo or a corrupt file, e.g. a latency of 1e9 s
# that would ask for a 178 TiB delay line): (prefix or suffix, low, high)
FILE_RANGES = (("_s", 0.0, 2.0),  # latencies, holds, onsets (s)
               ("delay_scale", 1e-3, 10.0),  # every delay times this
               ("g_", 0.0, 100.0), ("k_", 0.0, 100.0), ("kp_", 0.0, 100.0),
               ("kd_", 0.0, 100.0),  # reflex and balance gains
               ("s0", 0.0, 1.0),  # prestimulations (excitations)
               ("l_off_", 0.0, 3.0))  # length offsets (optimal fibre lengths)
FILE_RANGE_OTHER = (-10.0, 10.0)  # angles (rad), distances (m), loads, placement terms


def file_range(name: str) -> tuple[float, float]:
    """The sanity range of a parameter file's field ``name`` (``FILE_RANGES``)."""
    for key, lo, hi in FILE_RANGES:
        if name == key or (key.startswith("_") and name.endswith(key)) or (
                not key.startswith("_") and name.startswith(key)):
            return lo, hi
    return FILE_RANGE_OTHER


def named_file(name):
    """The shipped file of a named parameter set (``NAMED``), or None for another name."""
    if str(name) not in NAMED:
        return None
    return resources.files("stumble.control.reflex") / "data" / NAMED[str(name)]


def file_sha256(path) -> str:
    """SHA-256 of a parameter file, or of a shipped set's by name (``NAMED``), for a
    fit's record."""
    import hashlib
    from pathlib import Path

    return hashlib.sha256((named_file(path) or Path(path)).read_bytes()).hexdigest()


def load_params(path) -> GH2010Params:
    """Parameters from a ``gh2010.json`` (a fit's result), or a shipped set by name
    (``NAMED``: ``walk``, the first walking fit; ``trip``, the trip stages on it;
    ``pushed-walk``, the walking fit with pushes; ``pushed``, the touch stages on it;
    ``knee-walk``, that walking fit refitted with the knee term; ``knee``, the touch stage
    on it; ``knee-foot``, a touch stage on it by the foot's phase; ``knee-2ms``,
    ``knee``'s touch stage refitted at a 2 ms step; ``knee-2ms-dense``, a second touch
    stage on it; ``knee-2ms-dense-wide``, a third; ``knee-2ms-dense-wide-s3``, the third
    by another seed, the default; ``expert-placement``, the network's expert, and
    ``expert-touch``, a touch stage on it); InputError if it is not one."""
    from pathlib import Path

    shipped = named_file(path)
    if shipped is not None:
        return GH2010Params.from_json(json.loads(shipped.read_text())["params"])
    path = Path(path)
    if not path.is_file():
        raise InputError(f"GH2010 parameter file {path} does not exist or is not a file "
                         f"(the shipped sets by name: {', '.join(NAMED)})")
    try:
        obj = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(f"{path} is not a GH2010 parameter file ({e})") from None
    if not isinstance(obj, dict) or not isinstance(obj.get("params"), dict):
        raise InputError(f"{path} is not a GH2010 parameter file (no 'params' object)")
    return GH2010Params.from_json(obj["params"])


def shipped_params(wiring: str = "gh2010", walking_only: bool = False) -> GH2010Params:
    """The closed-loop-optimised parameters shipped with stumble for a wiring (the
    paper's if none is shipped); ``walking_only``: the walking fit the trip stage starts
    from (``SHIPPED_WALKING``), where one is shipped apart."""
    name = SHIPPED[wiring]
    if walking_only and wiring in SHIPPED_WALKING:
        name = SHIPPED_WALKING[wiring]
    path = resources.files("stumble.control.reflex") / "data" / name
    if not path.is_file():
        return GH2010Params(wiring=wiring)
    return replace(GH2010Params.from_json(json.loads(path.read_text())["params"]),
                   wiring=wiring)


def fitted_timestep(params: GH2010Params | None = None) -> float:
    """The physics step (s) a set was fitted at (default: the shipped default set's)."""
    return (params or shipped_params()).timestep_s


def seed003_delays_s(muscles: tuple[str, ...]) -> dict:
    """Path delays (s) of the GH2010 laws through seed 003's nerves (Table I, afferents
    57.6 m/s, efferents 52.4 m/s): each muscle's own loop (its shortest, over the spinal
    segments it is bound to), SOL onto TA (through their shared S1), and the foot-contact
    afferents onto each muscle bound to S1 or S2 (None for a muscle with no such path)."""
    from stumble.control.reflex.network import (
        AFFERENT_M_PER_S,
        CONTACT_NERVE_M,
        EFFERENT_M_PER_S,
        NERVE_LENGTH_M,
    )

    def path(src: dict, dst: dict) -> float | None:
        shared = [src[s] / AFFERENT_M_PER_S + dst[s] / EFFERENT_M_PER_S
                  for s in src if s in dst]
        return min(shared) if shared else None

    own = {m: path(NERVE_LENGTH_M[m], NERVE_LENGTH_M[m]) for m in muscles}
    gate = {m: path(CONTACT_NERVE_M, NERVE_LENGTH_M[m]) for m in muscles}
    return {"own": own, "sol_ta": path(NERVE_LENGTH_M["SOL"], NERVE_LENGTH_M["TA"]),
            "gate": gate}


class GH2010Controller:
    """Geyer & Herr 2010's reflexes driving the planar body's muscles.

    ``params.wiring``: ``gh2010`` (the paper's laws and delays, the default), or ``seed003``:
    the same laws restricted to what seed 003's network can express, on its nerves: each
    reflex delayed by its path through Table I (``seed003_delays_s``), the stance/swing
    switch of a muscle by its foot-contact path (``network.CONTACT_NERVE_M``, L4-S2; HFL,
    which no contact afferent reaches, keeps its swing law in both phases), without the
    law that needs a path Table I does not have (HAMS onto HFL), and the trunk-lean and
    double-support laws through the 20 ms latency of the network's addition
    (``controller.TrunkBalance``), which senses the lean, both feet's loads and where the
    feet are. It is the expert the network learns from.
    """

    name = "gh2010"
    uses_sensors = False  # reads the sensor rows of each block (``observe``) instead

    def __init__(self, params: GH2010Params | None = None):
        self.p = params or GH2010Params()
        self.wiring = self.p.wiring
        if self.wiring not in WIRINGS:
            raise InputError(f"GH2010 wiring {self.wiring!r} is not one of {', '.join(WIRINGS)}")
        if self.p.scr_phase not in SCR_PHASES:
            raise InputError(f"GH2010 scr_phase {self.p.scr_phase!r} is not one of "
                             f"{', '.join(SCR_PHASES)}")
        if self.p.load_from not in LOAD_SOURCES:
            raise InputError(f"GH2010 load_from {self.p.load_from!r} is not one of "
                             f"{', '.join(LOAD_SOURCES)}")
        self.lean_free: np.ndarray | None = None  # set to anything to also get the laws'
        # output without their trunk-lean terms after each update
        self.log: list[tuple[str, float]] = []
        self._state = "reflex"

    # ---- set-up -----------------------------------------------------------------
    def start(self, ctx: Context) -> None:
        """Bind to the body's muscles and sensors, fill the delays with the present."""
        m, body = ctx.model, ctx.body
        if not body.muscles:
            raise InputError("the GH2010 controller needs the musculoskeletal body")
        self.lay = body.sensors
        geos = body.muscles  # right leg's muscles, then the left's, same order
        names = [g.name[:-2] for g in geos[: len(geos) // 2]]
        self.names = names
        self.nm = len(names)
        self.idx = ix = {n: i for i, n in enumerate(names)}
        self.flexor = "HFL" if "HFL" in ix else "RF"
        self.f_max = np.array([g.f_max_n for g in geos])
        self.l_ref = np.array([g.l_ref_m for g in geos])
        self.l0 = np.array([g.l0_m for g in geos])
        self.weight_n = float(m.body_mass.sum()) * 9.81
        self.act_ids = np.array([m.actuator(g.name).id for g in geos])
        self.act_adr = m.actuator_actadr[self.act_ids]
        lo = int(self.act_ids[0])  # contiguous actuators (as built): written through a slice
        self._act_cols = (slice(lo, lo + self.act_ids.size) if np.array_equal(
            self.act_ids, np.arange(lo, lo + self.act_ids.size)) else self.act_ids)
        self._channel_map()
        self._build_taps(m.opt.timestep)
        self._w_stance, self._w_swing = self._law_matrices()
        self._feature_map()
        self._ungated = ~self.gated
        self.delay.fill(self._channels(ctx.data.sensordata[None])[0])
        self.period_steps = self.delay.block
        self.plan = np.empty((self.period_steps, m.nu))
        lumbar = m.joint("lumbar_extension")  # the upper body held as at the start
        ctx.data.ctrl[m.actuator("lumbar_extension").id] = ctx.data.qpos[lumbar.qposadr[0]]
        self._no_plan = np.empty((0, m.nu))
        # the plan's first muscle column, when the muscles are one slice (else the plan is
        # filled by NumPy, and the kernel gets a plan of no rows and this 0)
        self._act_first = (self._act_cols.start if isinstance(self._act_cols, slice)
                           else None)
        self._ungated_b = self._ungated.astype(np.bool_)
        self._bind_compiled()
        self._held = ctx.data.ctrl
        u = self._excitations(self.delay.read(1))[0]
        ctx.data.act[self.act_adr] = u  # muscles start at the reflexes' present output
        self.log.append(("reflex", 0.0))

    def _build_taps(self, dt: float) -> None:
        """The (channel, lag) reads of every law, for this wiring and time step."""
        from stumble.control.reflex.controller import TrunkBalance

        p, nm, ix, names = self.p, self.nm, self.idx, self.names
        ticks = lambda s: max(1, round(s * p.delay_scale / dt))  # noqa: E731
        resp = p.delay_scale * p.response_delay_scale  # the touch's reflexes
        rticks = lambda s: max(1, round(s * resp / dt))  # noqa: E731
        joint = {j: ticks(d) for j, d in DELAY_BY_JOINT_S.items()}
        if self.wiring == "gh2010":
            own = [joint[JOINT_OF[n]] for n in names]
            sol_ta, ham_flex = joint["ankle"], joint["hip"]
            knee = joint["knee"]
            gate = [joint["hip"]] * nm
            vest, ds = joint["hip"], joint["hip"]
            self.gated = np.ones(nm, bool)
        else:
            d = seed003_delays_s(tuple(names))
            own = [ticks(d["own"][n]) for n in names]
            sol_ta = ticks(d["sol_ta"])
            ham_flex, ds = None, None  # no such paths in Table I
            knee = own[ix["VAS"]]  # the knee's angle reaches VAS as its own stretch
            self.gated = np.array([d["gate"][n] is not None for n in names])
            gate = [ticks(d["gate"][n]) if d["gate"][n] is not None else own[j]
                    for j, n in enumerate(names)]  # (an ungated muscle's is never used)
            vest = ticks(TrunkBalance.DELAY_S)
        self.lags = {"own": own, "sol_ta": sol_ta, "ham_flex": ham_flex, "knee": knee,
                     "gate": gate, "vest": vest, "ds": ds}
        # channels: F (2·nm), L (2·nm), knee flexion (2), its rate (2), load (2, body
        # weights), foot x (2), obstacle touches (2), lean rate, lean (``_channel_map``)
        cF, cL = (lambda leg, j: leg * nm + j), (lambda leg, j: 2 * nm + leg * nm + j)
        o = 4 * nm
        c_knee, c_knee_v, c_load, c_x, c_touch = o, o + 2, o + 4, o + 6, o + 8
        c_lean_v, c_lean = o + 10, o + 11
        taps, at = [], {}

        def tap(key, col, lag):
            at[key] = len(taps)
            taps.append((col, lag))

        for leg in range(2):
            for j in range(nm):
                tap(("F", leg, j), cF(leg, j), own[j])
                tap(("L", leg, j), cL(leg, j), own[j])
                tap(("gate", leg, j), c_load + leg, gate[j])
            tap(("F_sol_ta", leg), cF(leg, ix["SOL"]), sol_ta)
            if ham_flex is not None:
                tap(("L_ham_flex", leg), cL(leg, ix["HAMS"]), ham_flex)
            tap(("knee", leg), c_knee + leg, knee)
            tap(("knee_v", leg), c_knee_v + leg, knee)
            tap(("vest_load", leg), c_load + leg, vest)
            tap(("vest_x", leg), c_x + leg, vest)
            if ds is not None:
                tap(("ds_load", leg), c_load + leg, ds)
                tap(("ds_x", leg), c_x + leg, ds)
            tap(("touch", leg), c_touch + leg, rticks(p.scr_latency_s))
            tap(("x_touch", leg), c_x + leg, rticks(p.scr_latency_s))
        tap("lean", c_lean, vest)
        tap("lean_v", c_lean_v, vest)
        n_channels = c_lean + 1
        if self._place:  # after the lean: α (2), COM ahead of the other ankle (2), COM vx
            for k in range(5):
                tap(("place", k), n_channels + k, vest)
            n_channels += 5
        # the taps in the order the laws read them, each group contiguous, so that a
        # block's reads are slices of one gather (``_excitations``; a tap read by two
        # groups, as seed003's flexor stretch, is read twice); the others after them
        flex = ix[self.flexor]
        pair = lambda name: [(name, leg) for leg in range(2)]  # noqa: E731
        groups = {
            "phi": [k for leg in range(2) for k in (
                *[("F", leg, ix[mus]) for mus in ("SOL", "GAS", "VAS", "GLU", "HAMS")],
                ("L", leg, ix["TA"]), ("L", leg, flex),
                ("L_ham_flex", leg) if ham_flex is not None else ("L", leg, flex),
                ("knee", leg), ("F_sol_ta", leg))],
            "gate": [("gate", leg, j) for leg in range(2) for j in range(nm)],
            "knee_v": pair("knee_v"),
            "ds_load": pair("ds_load") if ds is not None else [],
            "ds_x": pair("ds_x") if ds is not None else [],
            "vest_load": pair("vest_load"), "vest_x": pair("vest_x"),
            "touch": pair("touch"), "x_touch": pair("x_touch"), "lean": ["lean", "lean_v"],
            "place": [("place", k) for k in range(5)] if self._place else []}
        order, self._sl = [], {}
        for name, keys in groups.items():
            self._sl[name] = slice(len(order), len(order) + len(keys))
            order += [at[k] for k in keys]
        order += [i for i in range(len(taps)) if i not in set(order)]
        first: dict[int, int] = {}
        for new, old in enumerate(order):
            first.setdefault(old, new)
        self.at = at = {k: first[i] for k, i in at.items()}
        self.delay = DelayTaps(n_channels, [taps[i] for i in order])
        self._has_ds = ds is not None
        self._iLean, self._iLeanV = at["lean"], at["lean_v"]
        self._touched = np.zeros(2, bool)  # each foot touched at the last tick
        self._ahead = np.zeros(2, bool)  # it was ahead of the other at its last onset
        # (a model without an obstacle is never touched: nothing to add)
        self._scr = p.stumble_reflex and self.lay.obstacle_found is not None
        self._scr_since = np.full(2, np.inf)  # ticks since each foot's last (sensed) touch
        self._dt = dt
        self._touch_weights()
        self._armed = np.zeros(2, bool)  # each leg's next step is to cross
        self._cross_since = np.full(2, np.iinfo(np.int64).max // 2)  # ticks since its onset
        self._was_on = np.ones(2, bool)  # each foot loaded at the last tick
        self._mark = -np.inf  # where the obstacle was touched (foot x, m)
        self._mark_box = np.full(1, -np.inf)  # the compiled path's (``kernels.gh_touch``)
        self._no_sets = np.zeros((3, 2, 2, nm))
        self._no_any = np.zeros((2, 2, nm))
        self._f_cols = [ix[k] for k in ("GAS", "VAS", "GLU", "HAMS")]
        self._l_cols = [ix["TA"], ix[self.flexor]]
        self._l_offs = np.array([p.l_off_ta, p.l_off_hfl])
        # the trunk-lean laws reach the hip extensors (GLU, HAMS) and the flexor only
        self._i_glu, self._i_hams, self._i_flex = ix["GLU"], ix["HAMS"], ix[self.flexor]

    def _touch_weights(self) -> None:
        """What the reflexes a touch triggers add, from the parameters (``TOUCH_FIELDS``):
        no state, so that ``retouch`` can set them again."""
        p, nm, ix, dt = self.p, self.nm, self.idx, self._dt
        scale = p.delay_scale * p.response_delay_scale
        self._scr_hold = max(1, round(p.scr_hold_s * scale / dt))
        w = np.zeros((3, 2, 2, nm))  # (set, touched leg, leg, muscle): the tripped
        # leg's flexion set, its extension set, the other leg's
        for leg in range(2):
            for name, gain in (("HAMS", p.g_scr_ham), ("TA", p.g_scr_ta),
                               (self.flexor, p.g_scr_flex)):
                w[0, leg, leg, ix[name]] += gain
            for name, gain in (("RF", p.g_scr_ext_rf), ("SOL", p.g_scr_ext_sol),
                               ("GLU", p.g_scr_ext_glu), ("HAMS", p.g_scr_ext_ham)):
                # (without the iliopsoas RF is also the flexion set's hip flexor)
                w[1, leg, leg, ix[name]] += gain
            for name, gain in (("SOL", p.g_scr_sol), ("GAS", p.g_scr_gas),
                               ("GLU", p.g_scr_glu)):
                w[2, leg, 1 - leg, ix[name]] += gain
        self._scr_by_foot = p.scr_phase == "foot"
        # ``any``: the three sets act together, one matrix (touched leg, leg, muscle)
        self._w_scr = w if self._scr_by_foot else w.sum(axis=0)
        self._scr_vas_after = round(p.scr_vas_after_s * scale / dt)
        self._w_scr_vas = np.zeros((2, 2, nm))
        for leg in range(2):
            self._w_scr_vas[leg, leg, ix["VAS"]] = p.g_scr_vas
        self._cross = self._scr and p.crossing
        self._w_cross = np.zeros(nm)  # (muscle,) the crossing drive of either leg
        for name, gain in ((self.flexor, p.g_cross_flex), ("HAMS", p.g_cross_ham),
                           ("TA", p.g_cross_ta), ("GAS", p.g_cross_gas)):
            self._w_cross[ix[name]] += gain
        self._cross_hold = max(1, round(p.cross_hold_s * scale / dt))

    def walk_key(self) -> tuple:
        """What the walk before a first touch depends on: every parameter but those of
        the reflexes a touch triggers (``TOUCH_FIELDS``), and whether they are on."""
        p = self.p
        return (*(getattr(p, f.name) for f in fields(p) if f.name not in TOUCH_FIELDS),
                p.stumble_reflex, p.crossing)

    def touch_settings(self) -> GH2010Params:
        """What ``retouch`` takes: the parameters."""
        return self.p

    def retouch(self, params: GH2010Params) -> None:
        """Go on with ``params``, which differ from the present ones only in the reflexes
        a touch triggers (``TOUCH_FIELDS``): before a touch those add nothing, so a
        walk to that instant is the same with either (``pipeline.WalkInCache``)."""
        before = self.walk_key()
        was, self.p = self.p, params
        if self.walk_key() != before:
            self.p = was
            raise ValueError("retouch: the parameters differ in more than the touch's "
                             "reflexes")
        self._touch_weights()

    def _channel_map(self) -> None:
        """One gather and one affine map from a sensor row to the channels: F (F_max),
        L (l_opt), knee flexion and its rate, load (body weights), foot x, lean rate; and
        the torso axis' x and z, of which the lean is the angle."""
        lay, nm2 = self.lay, 2 * self.nm
        touch = lay.obstacle_found  # a model without an obstacle: never touched
        self._gather = np.concatenate([
            lay.muscle_force, lay.muscle_length, lay.joint_angle[:, 1],
            lay.joint_velocity[:, 1], lay.foot_force[:, 2], lay.foot_pos[:, 0],
            lay.foot_found if touch is None else touch,
            [lay.torso_angvel[1], lay.torso_z[0], lay.torso_z[2]]]).astype(int)
        w = self.weight_n
        self._scale = np.concatenate([-1.0 / self.f_max, 1.0 / self.l0, [-1.0] * 4,
                                      [-1.0 / w] * 2, [1.0] * 2,
                                      [0.0 if touch is None else 1.0] * 2, [1.0] * 3])
        self._offset = np.concatenate([np.zeros(nm2), 1.0 - self.l_ref / self.l0,
                                       np.zeros(13)])
        # ``load_from`` any: the obstacle's vertical force joins the floor's in the load
        self._ob_load = (lay.obstacle_force[:, 2].astype(int) if self.p.load_from == "any"
                         and lay.obstacle_force is not None else None)
        self._c_load = 2 * nm2 + 4
        # swing-leg placement (``k_place`` not 0): pelvis x, z; ankles x, z; COM x, vx
        self._place = self.p.k_place != 0.0
        self._place_cols = np.concatenate([
            lay.pelvis[[0, 2]], lay.foot_pos[:, 0], lay.foot_pos[:, 2],
            [lay.com[0], lay.com_vel[0]]]).astype(int)

    def _channels(self, rows: np.ndarray) -> np.ndarray:
        """(n, channels) sensed signals from sensor rows (n, nsensordata)."""
        kern = kernels()
        if kern is not None:  # the same numbers, compiled (``kernels``)
            v = np.empty((len(rows), len(self._gather)))
            kern["gh_channels"](rows, self._gather, self._scale, self._offset, v)
        else:
            v = rows[:, self._gather]
            v *= self._scale
            v += self._offset
        if self._ob_load is not None:
            v[:, self._c_load:self._c_load + 2] -= rows[:, self._ob_load] / self.weight_n
        v[:, -2] = np.arctan2(v[:, -2], v[:, -1])  # forward lean
        if not self._place:
            return v[:, :-1]
        k = v.shape[1] - 1
        out = np.empty((len(v), k + 5))  # the channels, then α (2), ahead (2), speed
        if kern is not None:
            a, b = np.empty((len(v), 2)), np.empty((len(v), 2))
            kern["gh_place_in"](rows, self._place_cols, v, out, a, b)
            np.arctan2(a, b, out=out[:, k:k + 2])
            return out
        r = rows[:, self._place_cols]  # pelvis x, z, ankle x (2), ankle z (2), COM x, vx
        out[:, :k] = v[:, :-1]
        np.arctan2(r[:, 2:4] - r[:, :1], r[:, 1:2] - r[:, 4:6], out=out[:, k:k + 2])
        np.subtract(r[:, 6:7], r[:, 3:1:-1], out=out[:, k + 2:k + 4])  # COM ahead of the
        out[:, k + 4] = r[:, 7]  # other leg's ankle; the COM's forward speed
        return out

    # ---- the reflex laws ------------------------------------------------------------
    # the features of a leg's laws, in order: F of SOL, GAS, VAS, GLU, HAMS (own paths);
    # [l − l_off]+ of TA, the flexor, HAMS onto the flexor; the knee stop [φ_off − φ]+
    # while the knee extends; SOL's F onto TA (its own path); double support (gh2010)
    FEATURES = ("F_SOL", "F_GAS", "F_VAS", "F_GLU", "F_HAMS", "L_TA", "L_FLEX", "L_HAMS",
                "knee_stop", "F_SOL_TA", "ds")

    def _law_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(K + 1, nm) weights of the features (and a last row of prestimulations) in
        stance and in swing: u = [Φ 1]·W, the laws of the module docstring but the
        trunk-lean ones, each gain where its muscle and phase take it."""
        p, ix = self.p, self.idx
        fi = {f: k for k, f in enumerate(self.FEATURES)}
        one = len(self.FEATURES)
        st = np.zeros((one + 1, self.nm))
        sw = np.zeros_like(st)
        st[one], sw[one] = p.s0, p.s0
        flex = self.flexor
        st[fi["F_SOL"], ix["SOL"]] = p.g_sol
        st[fi["L_TA"], ix["TA"]] = p.g_ta
        st[fi["F_SOL_TA"], ix["TA"]] = -p.g_sol_ta
        st[fi["F_GAS"], ix["GAS"]] = p.g_gas
        st[one, ix["VAS"]] = p.s0_vas
        st[fi["F_VAS"], ix["VAS"]] = p.g_vas
        st[fi["knee_stop"], ix["VAS"]] = -p.k_phi
        for name in ("GLU", "HAMS", flex):
            st[one, ix[name]] = p.s0_bal
        st[fi["ds"], ix["GLU"]], st[fi["ds"], ix[flex]] = -p.k_bw, p.k_bw
        sw[fi["L_FLEX"], ix[flex]] = p.g_hfl
        sw[fi["L_HAMS"], ix[flex]] = -p.g_ham_hfl
        sw[fi["F_GLU"], ix["GLU"]] = p.g_glu
        sw[fi["F_HAMS"], ix["HAMS"]] = p.g_ham
        sw[fi["L_TA"], ix["TA"]] = p.g_ta
        if self.wiring == "seed003":
            st[fi["ds"]] = sw[fi["ds"]] = 0.0  # (through the addition instead)
            st[fi["L_HAMS"]] = sw[fi["L_HAMS"]] = 0.0  # no such path in Table I
            for name, j in ix.items():  # muscles no contact afferent reaches keep one
                if not self.gated[j] and name == "VAS":  # law: VAS its stance law,
                    sw[:, j] = st[:, j]
                elif not self.gated[j] and name == flex:  # the flexor its swing law
                    st[:, j] = sw[:, j]
        return st, sw

    def _feature_map(self) -> None:
        """The gather, sign, offset and floor that turn the taps into the features."""
        p = self.p
        # the features' taps are the layout's first 20 (``_build_taps``: per leg, F of
        # SOL, GAS, VAS, GLU, HAMS, L of TA, the flexor, HAMS onto the flexor (seed003:
        # the flexor's, a zero weight), the knee, SOL's F onto TA)
        self._phi_sign = np.array([1.0] * 8 + [-1.0, 1.0])
        self._phi_off = np.array([0.0] * 5 + [p.l_off_ta, p.l_off_hfl, p.l_off_ham,
                                              -p.phi_off, 0.0])
        self._phi_low = np.array([-np.inf] * 5 + [0.0] * 4 + [-np.inf])
        self._w_st, self._b_st = self._w_stance[:-1], self._w_stance[-1]
        self._w_sw, self._b_sw = self._w_swing[:-1], self._w_swing[-1]
        if not self._has_ds:  # no double-support feature in the reflex part
            self._w_st, self._w_sw = self._w_st[:-1], self._w_sw[:-1]
        self._n_feat = len(self._w_st)
        self._all_gated = bool(self.gated.all())

    def _bind_compiled(self) -> None:
        """What the compiled paths read, gathered once at ``start``: the taps and numbers
        of the laws (``kernels.gh_laws``, ``gh_features``, ``gh_touch``; the parameters as
        given, int or float: the same IEEE operations either way), kept scratch per block
        length, and whether ``update`` can be one call (``_update_fused``)."""
        p, sl = self.p, self._sl
        self._feat_taps = (sl["phi"].start, sl["knee_v"].start,
                           sl["ds_load"].start if self._has_ds else 0,
                           sl["ds_x"].start if self._has_ds else 0, sl["gate"].start)
        self._law_ip = np.array([
            self._iLean, self._iLeanV, sl["vest_load"].start, sl["vest_x"].start,
            self._i_glu, self._i_hams, self._i_flex, int(self._place),
            sl["place"].start, int(self.wiring == "seed003"),
            int(bool(p.place_cd or p.place_cv))], dtype=np.int64)
        self._law_fp = np.array([p.lean_ref, p.kp_trunk, p.kd_trunk, p.k_lean,
                                 p.stance_load, p.k_bw, p.k_place, p.place_a0, p.place_cd,
                                 p.place_cv], dtype=float)
        self._sense_at: dict[int, tuple] = {}  # ``observe``'s scratch per block length
        self._angles: dict[int, tuple] = {}  # ``_angles_at``'s
        self._upd_at: dict[int, tuple] = {}  # ``_update_fused``'s scratch per block length
        self._tap_idx = None  # ``run_blocks``' delayed taps' indices
        self._no_cols = np.zeros(0, dtype=np.int64)
        self._touch_taps = (sl["touch"].start, sl["x_touch"].start, sl["vest_load"].start,
                            sl["vest_x"].start)
        self._meta = np.zeros(16, dtype=np.int64)  # NumPy's loops' arguments (``kernels``)
        # one compiled call a block where the laws' weights are NumPy's C-contiguous
        self._fused = all(w.flags.c_contiguous and w.dtype == np.float64
                          for w in (self._w_st, self._w_sw))

    def _excitations_compiled(self, kern: dict, x: np.ndarray,
                              plan: np.ndarray) -> np.ndarray:
        """``_excitations`` with its elementwise steps compiled (``kernels``; NumPy's
        matrix products): the same numbers; with ``plan`` rows, written into them too."""
        p, n, nm, sl = self.p, len(x), self.nm, self._sl
        v = np.empty((n, 2, self._n_feat))
        stance = np.empty((n, 2, nm), dtype=np.bool_)
        phi0, knee_v0, ds_load, ds_x, gate0 = self._feat_taps
        kern["gh_features"](x, phi0, self._phi_sign, self._phi_off, self._phi_low, knee_v0,
                            self._has_ds, ds_load, ds_x, p.stance_load, gate0,
                            self._ungated_b, v, stance)
        u = np.empty((n, 2, nm))
        # ``gh_select``, ``gh_lean`` and ``gh_place`` in one call (``_bind_compiled``)
        kern["gh_laws"](stance, v @ self._w_st, self._b_st, v @ self._w_sw, self._b_sw, x,
                        self._law_ip, self._law_fp, u)
        u = u.reshape(n, 2 * nm)
        if self._scr:
            by_foot = self._scr_by_foot
            self._mark_box[0] = self._mark
            kern["gh_touch"](x, sl["touch"].start, sl["x_touch"].start, sl["vest_load"].start,
                             sl["vest_x"].start, p.stance_load, self._scr_hold,
                             self._scr_vas_after, by_foot, p.scr_ahead_m,
                             self._w_scr if by_foot else self._no_sets,
                             self._no_any if by_foot else self._w_scr, self._w_scr_vas,
                             self._cross, self._cross_hold, p.cross_ahead_m, self._w_cross,
                             self._scr_since, self._touched, self._ahead, self._armed,
                             self._cross_since, self._was_on, self._mark_box, u)
            self._mark = float(self._mark_box[0])
        kern["clip_plan"](u, PRE_ACTIVATION, plan, self._act_first or 0, self._held)
        return u

    def _excitations(self, x: np.ndarray, plan: np.ndarray | None = None) -> np.ndarray:
        """Excitations (n, 2·nm) of both legs from the block's taps (n, taps); with
        ``plan`` (n, nu), its rows are also set: the controls now, the muscles' from
        these (only where the compiled kernels run: the caller checks ``_plan_done``)."""
        kern = kernels()
        self._plan_done = False
        if kern is not None and self.lean_free is None:
            self._plan_done = plan is not None and self._act_first is not None
            return self._excitations_compiled(
                kern, x, plan if self._plan_done else self._no_plan)
        p, n, nm, sl = self.p, len(x), self.nm, self._sl
        t = x[:, sl["phi"]].reshape(n, 2, 10) * self._phi_sign
        t -= self._phi_off
        v = np.empty((n, 2, self._n_feat))
        np.maximum(t, self._phi_low, out=v[..., :10])
        v[..., 8] *= x[:, sl["knee_v"]] < 0.0  # the knee stop acts while it extends
        if self._has_ds:
            load, fx = x[:, sl["ds_load"]], x[:, sl["ds_x"]]
            on = load > p.stance_load
            np.multiply(load[:, ::-1], on & on[:, ::-1] & (fx < fx[:, ::-1]), out=v[..., 10])
        stance = x[:, sl["gate"]].reshape(n, 2, nm) > p.stance_load
        if not self._all_gated:
            stance |= self._ungated
        u = np.where(stance, v @ self._w_st + self._b_st, v @ self._w_sw + self._b_sw)
        if self.lean_free is not None:  # the laws without the trunk-lean terms (labels)
            self.lean_free = np.clip(u.reshape(n, 2 * nm), PRE_ACTIVATION, 1.0)
        self._add_vestibular(x, u)
        if self._place:
            self._add_placement(x, u)
        u = u.reshape(n, 2 * nm)
        if self._scr:
            u += self._stumble(x).reshape(n, 2 * nm)
        np.maximum(u, PRE_ACTIVATION, out=u)  # np.clip's bounds, without its wrapper
        return np.minimum(u, 1.0, out=u)

    def _stumble(self, x: np.ndarray) -> np.ndarray:
        """The stumbling corrective reflex (n, 2, nm): for ``scr_hold_s`` after each
        sensed touch of a foot (``SCR_GAINS``), the knee extensor from
        ``scr_vas_after_s`` after it for as long; the tripped leg's flexion or extension
        set by where its foot was (``scr_phase`` foot) or both (any)."""
        sl = self._sl
        touched = x[:, sl["touch"]] > 0.0  # (n, 2)
        n = len(x)
        k = np.arange(n)[:, None]
        last = np.where(touched, k, -1)
        last = np.maximum.accumulate(last, axis=0)  # the latest touch in the block so far
        since = np.where(last >= 0, k - last, self._scr_since + 1 + k)
        self._scr_since = since[-1].astype(float)
        on = (since < self._scr_hold).astype(float)  # (n, 2)
        late = ((since >= self._scr_vas_after)
                & (since < self._scr_vas_after + self._scr_hold)).astype(float)
        starts = touched & ~np.vstack([self._touched[None], touched[:-1]])  # onsets
        self._touched = touched[-1].copy()
        if self._scr_by_foot:  # where each foot was at its touch's onset, held
            onset = np.where(starts, k, -1)
            first = np.maximum.accumulate(onset, axis=0)
            fx = x[:, sl["x_touch"]]
            now = fx - fx[:, ::-1] > self.p.scr_ahead_m  # (n, 2): ahead of the other
            ahead = np.where(first >= 0, np.take_along_axis(now, np.maximum(first, 0), axis=0),
                             self._ahead)
            self._ahead = ahead[-1].copy()
            gates = np.stack([on * ~ahead, on * ahead, on])  # (set, n, touched)
            now_on = np.einsum("snt,stlm->nlm", gates, self._w_scr)
        else:
            now_on = np.einsum("nt,tlm->nlm", on, self._w_scr)
        out = now_on + np.einsum("nt,tlm->nlm", late, self._w_scr_vas)
        if self._cross:
            out += self._crossing(touched, starts, x[:, sl["x_touch"]],
                                  x[:, sl["vest_load"]] > self.p.stance_load,
                                  x[:, sl["vest_x"]])
        return out

    def _crossing(self, touched: np.ndarray, starts: np.ndarray, x_touch: np.ndarray,
                  loaded: np.ndarray, x_foot: np.ndarray) -> np.ndarray:
        """The crossing step after a touch (n, 2, nm): a sensed touch arms both legs and
        marks the touched foot's x at its onset; a foot's landing launches the armed other
        leg's drive for ``cross_hold_s`` if that leg's foot is behind the mark."""
        n = len(touched)
        on = np.zeros((n, 2))
        armed, since, was = self._armed, self._cross_since, self._was_on
        for i in range(n):
            if starts[i].any():
                self._mark = float(x_touch[i][starts[i]].max()) + self.p.cross_ahead_m
            if touched[i].any():
                armed[:] = True
            land = loaded[i] & ~was
            was = loaded[i]
            for leg in (0, 1):
                if land[leg] and armed[1 - leg]:
                    armed[1 - leg] = False
                    if x_foot[i, 1 - leg] < self._mark:
                        since[1 - leg] = 0
            on[i] = since < self._cross_hold
            since += 1
        self._was_on = was.copy()
        return on[:, :, None] * self._w_cross

    def _add_vestibular(self, x: np.ndarray, u: np.ndarray) -> None:
        """Add the trunk-lean laws to ``u`` (n, 2, nm): stance hips k_p(θ − θ_ref) + k_d θ̇
        rectified (extensors [g]+, the flexor [−g]+), in proportion to each leg's share of
        the load; the swing flexor k_lean(θ − θ_ref) on a leg below the stance load
        (``controller.TrunkBalance``, rectified). Only these three muscles get a term."""
        p = self.p
        lean = x[:, self._iLean] - p.lean_ref
        g = p.kp_trunk * lean + p.kd_trunk * x[:, self._iLeanV]
        load = x[:, self._sl["vest_load"]]
        total = load.sum(axis=1, keepdims=True)
        share = np.where(total > 0.0, load / np.where(total > 0.0, total, 1.0), 0.5)
        ext = np.maximum(g, 0.0)[:, None] * share  # (n, 2)
        swing = load < p.stance_load
        flex = np.maximum(-g, 0.0)[:, None] * share + swing * (p.k_lean * lean)[:, None]
        glu = ext
        if self.wiring == "seed003":  # double support through the addition's senses
            on, xf = ~swing, x[:, self._sl["vest_x"]]
            rear = on & on[:, ::-1] & (xf < xf[:, ::-1])
            bw = p.k_bw * load[:, ::-1] * rear
            glu = ext + bw * -1.0
            flex = flex + bw
        u[:, :, self._i_glu] += glu
        u[:, :, self._i_hams] += ext
        u[:, :, self._i_flex] += flex

    def _add_placement(self, x: np.ndarray, u: np.ndarray) -> None:
        """Add the swing-leg placement to ``u`` (n, 2, nm): on a leg below the stance load
        and ahead of vertical, the flexor k_place·[α_tgt − α]+, GLU k_place·[α − α_tgt]+
        (``GH2010Params.k_place``)."""
        p, sl = self.p, self._sl["place"]
        pl = x[:, sl]
        alpha = pl[:, 0:2]
        if p.place_cd or p.place_cv:
            ahead, speed = pl[:, 2:4], pl[:, 4:5]
            e = p.k_place * (p.place_a0 + p.place_cd * ahead + p.place_cv * speed - alpha)
        else:  # the same numbers: a0 + (±0) + (±0) is a0 (the sensed values are finite)
            e = p.k_place * (p.place_a0 - alpha)
        on = (x[:, self._sl["vest_load"]] < p.stance_load) & (alpha > 0.0)
        u[:, :, self._i_flex] += on * np.maximum(e, 0.0)
        u[:, :, self._i_glu] += on * np.maximum(-e, 0.0)

    # ---- Controller protocol -----------------------------------------------------------
    def update(self, ctx: Context) -> np.ndarray:
        """The next block's excitations, from what its shortest path has sensed."""
        self._held = ctx.data.ctrl
        kern = kernels()
        if (kern is not None and kern["loops"] is not None and self._fused
                and self.lean_free is None):
            return self._update_fused(kern, ctx)
        u = self._excitations(self.delay.read(self.period_steps), self.plan)
        if self._plan_done:
            return self.plan
        self.plan[:] = ctx.data.ctrl
        self.plan[:, self._act_cols] = u
        return self.plan

    def _update_fused(self, kern: dict, ctx: Context) -> np.ndarray:
        """``update`` as one compiled call (``kernels.gh_update``: the delayed taps, the
        laws with NumPy's own matrix-product loop, the touch's reflexes, the plan)."""
        n, d = self.period_steps, self.delay
        idx = d.read_index(n)
        self._update_fused_scratch(n)
        x, u = self._upd_at[n][0], self._upd_at[n][5]
        if self._scr:
            self._mark_box[0] = self._mark
        in_kernel = self._act_first is not None
        kern["gh_update"](kern["loops"], self._meta, d.buf, idx, x, *self._law_args(n),
                          self.plan if in_kernel else self._no_plan, self._act_first or 0,
                          self._held)
        if self._scr:
            self._mark = float(self._mark_box[0])
        if in_kernel:
            return self.plan
        self.plan[:] = ctx.data.ctrl
        self.plan[:, self._act_cols] = u.reshape(n, -1)
        return self.plan

    def observe(self, rows: np.ndarray) -> None:
        """Store the block's sensed channels."""
        kern = kernels()
        if kern is None or self._ob_load is not None:
            return self.delay.push(self._channels(rows))
        # ``_channels`` then ``push``, compiled around NumPy's arctan2 (the same numbers)
        n = len(rows)
        v, a, b, extra = self._sense_scratch(n)
        d = self.delay
        if kern["loops"] is not None:  # one call, NumPy's arctan2 loop in it
            lean, alpha = self._angles_at(n)
            kern["gh_observe"](kern["loops"], self._meta, rows, self._gather, self._scale,
                               self._offset, v, self._place, self._place_cols, a, b, extra,
                               lean, alpha, d.buf, d.k)
        else:
            kern["gh_sense"](rows, self._gather, self._scale, self._offset, v, self._place,
                             self._place_cols, a, b, extra)
            kern["gh_push"](v, np.arctan2(v[:, -2], v[:, -1]), self._place,
                            np.arctan2(a, b) if self._place else a, extra, d.buf, d.k)
        d.k += n

    def run_blocks(self, physics, n: int, guard) -> tuple | None:
        """Up to ``n`` whole blocks, the physics included, in one compiled call
        (``kernels.gh_run``; ``sim.Controller``): the numbers of ``update``, the block's
        rollout and ``observe``, block by block, bit for bit. None where those are not
        one compiled call each (no kernels or NumPy's loops, the lean-free laws asked
        for, loads sensed otherwise, muscles not one slice of the controls). Returns
        (states, sensor rows, controls, blocks run): views of kept buffers, good until
        the next call."""
        kern = kernels()
        if (kern is None or kern["loops"] is None or not self._fused or n < 1
                or self.lean_free is not None or self._ob_load is not None
                or self._act_first is None):
            return None
        from stumble.sim import CONTACT_FORCE_MIN_N, NATIVE_BLOCKS_MAX, native_scratch

        ps, d = self.period_steps, self.delay
        n = min(n, NATIVE_BLOCKS_MAX)
        states, rows, plans = native_scratch(physics, NATIVE_BLOCKS_MAX * ps)
        kk = np.array([d.k], dtype=np.int64)
        if self._tap_idx is None or len(self._tap_idx) != ps:
            self._tap_idx = np.empty((ps, len(d.lags)), dtype=np.int64)
        idx = self._tap_idx
        self._update_fused_scratch(ps)
        if self._scr:
            self._mark_box[0] = self._mark
        sv, pa, pb, extra = self._sense_scratch(ps)
        lean, alpha = self._angles_at(ps)
        done = kern["gh_run"](
            physics.addr, physics.warnings, physics.ctrl, physics.sensordata, n, ps, states,
            rows, plans, guard.cols if guard is not None else self._no_cols,
            guard.fall_height_m if guard is not None else -np.inf,
            guard.foot_col if guard is not None else -1,
            guard is not None and guard.foot_on, CONTACT_FORCE_MIN_N, kk, d.size, d.lags,
            d.cols, idx,
            kern["loops"], self._meta, d.buf, self._upd_at[ps][0], *self._law_args(ps),
            self._act_first,
            self._gather, self._scale, self._offset, sv, self._place, self._place_cols, pa,
            pb, extra, lean, alpha)
        if self._scr:
            self._mark = float(self._mark_box[0])
        d.k = int(kk[0])
        self.plan[:] = plans[(done - 1) * ps:done * ps]
        self._held = physics.ctrl
        return states[:done * ps], rows[:done * ps], plans[:done * ps], done

    def _law_args(self, n: int) -> tuple:
        """``kernels.gh_update``'s arguments from the features' taps to the excitations'
        floor, for blocks of ``n`` ticks (its scratch made by ``_update_fused_scratch``;
        ``gh_run`` takes the same)."""
        p = self.p
        _x, v, stance, a, b, u = self._upd_at[n]
        phi0, knee_v0, ds_load, ds_x, gate0 = self._feat_taps
        touch0, xt0, load0, xf0 = self._touch_taps
        by_foot = self._scr_by_foot
        return (phi0, self._phi_sign, self._phi_off, self._phi_low, knee_v0, self._has_ds,
                ds_load, ds_x, p.stance_load, gate0, self._ungated_b, v, stance, self._w_st,
                a, self._b_st, self._w_sw, b, self._b_sw, self._law_ip, self._law_fp, u,
                self._scr, touch0, xt0, load0, xf0, self._scr_hold, self._scr_vas_after,
                by_foot, p.scr_ahead_m, self._w_scr if by_foot else self._no_sets,
                self._no_any if by_foot else self._w_scr, self._w_scr_vas, self._cross,
                self._cross_hold, p.cross_ahead_m, self._w_cross, self._scr_since,
                self._touched, self._ahead, self._armed, self._cross_since, self._was_on,
                self._mark_box, PRE_ACTIVATION)

    def _update_fused_scratch(self, n: int) -> None:
        """``_update_fused``'s kept buffers for blocks of ``n`` ticks (made once)."""
        if n not in self._upd_at:
            nm = self.nm
            self._upd_at[n] = (
                np.empty((n, self.delay.read_index(n).shape[1])),
                np.empty((n, 2, self._n_feat)), np.empty((n, 2, nm), dtype=np.bool_),
                np.empty((n, 2, nm)), np.empty((n, 2, nm)), np.empty((n, 2, nm)))

    def _sense_scratch(self, n: int) -> tuple:
        """``observe``'s kept buffers for blocks of ``n`` rows (made once)."""
        got = self._sense_at.get(n)
        if got is None:
            got = self._sense_at[n] = (np.empty((n, len(self._gather))),
                                       np.empty((n, 2)), np.empty((n, 2)),
                                       np.empty((n, 3)))
        return got

    def _angles_at(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Kept buffers of ``n`` ticks' lean (n,) and legs' angles (n, 2)."""
        got = self._angles.get(n)
        if got is None:
            got = self._angles[n] = (np.empty(n), np.empty((n, 2)))
        return got

    def state(self) -> str:
        """The reflexes have one state (each leg's stance or swing is internal)."""
        return self._state
