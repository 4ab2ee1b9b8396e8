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

All channels are read from MuJoCo sensor rows through a ``DelayLine``; every delay is at
least 5 ms, so the controller fixes 5 ms of excitations at a time and the physics loop
steps them natively.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields, replace
from importlib import resources

import numpy as np

from stumble.body.muscles import PRE_ACTIVATION
from stumble.control.reflex.delays import DelayLine
from stumble.errors import InputError
from stumble.sim import Context

SIDES = ("r", "l")
DELAY_BY_JOINT_S = {"hip": 0.005, "knee": 0.010, "ankle": 0.020}  # Geyer & Herr 2010
# the joint whose delay each muscle's own reflexes use (Geyer & Herr 2010)
JOINT_OF = {"HAMS": "hip", "GLU": "hip", "HFL": "hip", "RF": "hip", "VAS": "knee",
            "GAS": "ankle", "SOL": "ankle", "TA": "ankle"}
SHIPPED = "gh2010.json"  # optimised parameters shipped in stumble/control/reflex/data/
LEAN_FEATURES = [10, 11, 13]  # bal_ext, bal_flex, lean: the vestibular part of the laws


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
    delay_scale: float = 1.0  # every delay multiplied by this

    def free(self) -> list[str]:
        """Names of the gains a closed-loop fit may change (all but the delay scale)."""
        return [f.name for f in fields(self) if f.name != "delay_scale"]

    def vector(self) -> np.ndarray:
        """The free gains as a vector, in ``free()`` order."""
        return np.array([getattr(self, n) for n in self.free()])

    def with_vector(self, x: np.ndarray) -> GH2010Params:
        """A copy with the free gains from ``x``."""
        return replace(self, **{n: float(v) for n, v in zip(self.free(), x, strict=True)})

    def to_json(self) -> dict:
        """Plain numbers (for the shipped file and fit reports)."""
        return {k: float(v) for k, v in asdict(self).items()}

    @classmethod
    def from_json(cls, obj: dict) -> GH2010Params:
        """Read ``to_json``'s form; InputError naming an unknown or non-finite field."""
        names = {f.name for f in fields(cls)}
        bad = sorted(set(obj) - names)
        if bad:
            raise InputError(f"unknown GH2010 parameter(s): {', '.join(bad)}")
        vals = {}
        for k, v in obj.items():
            if not isinstance(v, int | float) or not np.isfinite(v):
                raise InputError(f"GH2010 parameter {k} must be a finite number, got {v!r}")
            vals[k] = float(v)
        return cls(**vals)


def load_params(path) -> GH2010Params:
    """Parameters from a ``gh2010.json`` (a fit's result); InputError if it is not one."""
    from pathlib import Path

    path = Path(path)
    if not path.is_file():
        raise InputError(f"GH2010 parameter file {path} does not exist or is not a file")
    try:
        obj = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(f"{path} is not a GH2010 parameter file ({e})") from None
    if not isinstance(obj, dict) or not isinstance(obj.get("params"), dict):
        raise InputError(f"{path} is not a GH2010 parameter file (no 'params' object)")
    return GH2010Params.from_json(obj["params"])


def shipped_params() -> GH2010Params:
    """The closed-loop-optimised parameters shipped with stumble (the paper's if none)."""
    path = resources.files("stumble.control.reflex") / "data" / SHIPPED
    if not path.is_file():
        return GH2010Params()
    return GH2010Params.from_json(json.loads(path.read_text())["params"])


class GH2010Controller:
    """Geyer & Herr 2010's reflexes driving the planar body's muscles."""

    name = "gh2010"
    uses_sensors = False  # reads the sensor rows of each block (``observe``) instead

    def __init__(self, params: GH2010Params | None = None):
        self.p = params or GH2010Params()
        self.lean_free: np.ndarray | None = None  # set to anything to also get the laws'
        # output without their trunk-lean terms after each update
        self.log: list[tuple[str, float]] = []
        self._state = "reflex"

    # ---- set-up -----------------------------------------------------------------
    def start(self, ctx: Context) -> None:
        """Bind to the body's muscles and sensors, fill the delays with the present."""
        m, body, p = ctx.model, ctx.body, self.p
        if not body.muscles:
            raise InputError("the GH2010 controller needs the musculoskeletal body")
        self.lay = body.sensors
        geos = body.muscles  # right leg's muscles, then the left's, same order
        names = [g.name[:-2] for g in geos[: len(geos) // 2]]
        self.names = names
        self.nm = len(names)
        self.idx = {n: i for i, n in enumerate(names)}
        self.flexor = "HFL" if "HFL" in self.idx else "RF"
        self.f_max = np.array([g.f_max_n for g in geos])
        self.l_ref = np.array([g.l_ref_m for g in geos])
        self.l0 = np.array([g.l0_m for g in geos])
        self.weight_n = float(m.body_mass.sum()) * 9.81
        self.act_ids = np.array([m.actuator(g.name).id for g in geos])
        self.act_adr = m.actuator_actadr[self.act_ids]
        dt = m.opt.timestep
        lag = {j: max(1, round(d * p.delay_scale / dt)) for j, d in DELAY_BY_JOINT_S.items()}
        # channels: F (2·nm), l (2·nm), knee flexion (2), its rate (2), load (2), foot x
        # (2), lean, lean rate
        muscle_lags = [lag[JOINT_OF[n]] for n in names] * 2
        lags = (muscle_lags + muscle_lags + [lag["knee"]] * 4 + [lag["hip"]] * 4
                + [lag["hip"]] * 2)
        self.period_steps = lag["hip"]
        self.delay = DelayLine(np.array(lags), self.period_steps)
        nm2 = 2 * self.nm
        self.c_f, self.c_l = slice(0, nm2), slice(nm2, 2 * nm2)
        o = 2 * nm2
        self.c_knee, self.c_knee_v = slice(o, o + 2), slice(o + 2, o + 4)
        self.c_load, self.c_x = slice(o + 4, o + 6), slice(o + 6, o + 8)
        self.c_lean, self.c_lean_v = o + 8, o + 9
        ix = self.idx
        self._f_cols = [ix[k] for k in ("SOL", "GAS", "VAS", "GLU", "HAMS")]
        self._l_cols = [ix["TA"], ix[self.flexor], ix["HAMS"]]
        self._l_offs = np.array([p.l_off_ta, p.l_off_hfl, p.l_off_ham])
        self._w_stance, self._w_swing = self._law_matrices()
        self.delay.fill(self._channels(ctx.data.sensordata[None])[0])
        self.plan = np.empty((self.period_steps, m.nu))
        lumbar = m.joint("lumbar_extension")  # the upper body held as at the start
        ctx.data.ctrl[m.actuator("lumbar_extension").id] = ctx.data.qpos[lumbar.qposadr[0]]
        u = self._excitations(self.delay.read(1))[0]
        ctx.data.act[self.act_adr] = u  # muscles start at the reflexes' present output
        self.log.append(("reflex", 0.0))

    def _channels(self, rows: np.ndarray) -> np.ndarray:
        """(n, channels) sensed signals from sensor rows (n, nsensordata)."""
        lay = self.lay
        f = -rows[:, lay.muscle_force] / self.f_max
        ln = 1.0 + (rows[:, lay.muscle_length] - self.l_ref) / self.l0
        knee = -rows[:, lay.joint_angle[:, 1]]  # flexion positive
        knee_v = -rows[:, lay.joint_velocity[:, 1]]
        load = -rows[:, lay.foot_force[:, 2]] / self.weight_n
        x = rows[:, lay.foot_pos[:, 0]]
        z = rows[:, lay.torso_z]
        lean = np.arctan2(z[:, 0], z[:, 2])
        lean_v = rows[:, lay.torso_angvel[1]]
        return np.column_stack([f, ln, knee, knee_v, load, x, lean, lean_v])

    # ---- the reflex laws ------------------------------------------------------------
    FEATURES = ("one", "F_SOL", "F_GAS", "F_VAS", "F_GLU", "F_HAMS", "L_TA", "L_FLEX", "L_HAMS",
                "knee_stop", "bal_ext", "bal_flex", "ds", "lean")

    def _law_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(K, nm) weights of the features in stance and in swing: u = Φ·W (the laws of
        the module docstring, each gain where its muscle and phase take it)."""
        p, ix, fi = self.p, self.idx, {f: k for k, f in enumerate(self.FEATURES)}
        st = np.zeros((len(self.FEATURES), self.nm))
        sw = np.zeros_like(st)
        st[fi["one"]], sw[fi["one"]] = p.s0, p.s0
        flex = self.flexor
        st[fi["F_SOL"], ix["SOL"]] = p.g_sol
        st[fi["L_TA"], ix["TA"]] = p.g_ta
        st[fi["F_SOL"], ix["TA"]] = -p.g_sol_ta
        st[fi["F_GAS"], ix["GAS"]] = p.g_gas
        st[fi["one"], ix["VAS"]] = p.s0_vas
        st[fi["F_VAS"], ix["VAS"]] = p.g_vas
        st[fi["knee_stop"], ix["VAS"]] = -p.k_phi
        for name in ("GLU", "HAMS", flex):
            st[fi["one"], ix[name]] = p.s0_bal
        st[fi["bal_ext"], ix["GLU"]] = st[fi["bal_ext"], ix["HAMS"]] = 1.0
        st[fi["bal_flex"], ix[flex]] = 1.0
        st[fi["ds"], ix["GLU"]], st[fi["ds"], ix[flex]] = -p.k_bw, p.k_bw
        sw[fi["L_FLEX"], ix[flex]] = p.g_hfl
        sw[fi["L_HAMS"], ix[flex]] = -p.g_ham_hfl
        sw[fi["lean"], ix[flex]] = p.k_lean
        sw[fi["F_GLU"], ix["GLU"]] = p.g_glu
        sw[fi["F_HAMS"], ix["HAMS"]] = p.g_ham
        sw[fi["L_TA"], ix["TA"]] = p.g_ta
        return st, sw

    def _excitations(self, x: np.ndarray) -> np.ndarray:
        """Excitations (n, 2·nm) of both legs from delayed channels (n, channels)."""
        p, n, nm = self.p, len(x), self.nm
        F = x[:, self.c_f].reshape(n, 2, nm)
        L = x[:, self.c_l].reshape(n, 2, nm)
        knee, knee_v = x[:, self.c_knee], x[:, self.c_knee_v]
        load, fx = x[:, self.c_load], x[:, self.c_x]
        lean, lean_v = x[:, self.c_lean], x[:, self.c_lean_v]
        stance = load > p.stance_load
        trailing = stance & stance[:, ::-1] & (fx < fx[:, ::-1])
        total = load.sum(axis=1, keepdims=True)
        share = load / np.maximum(total, 1e-9)
        bal = (p.kp_trunk * (lean - p.lean_ref) + p.kd_trunk * lean_v)[:, None]
        phi = np.empty((n, 2, len(self.FEATURES)))
        phi[..., 0] = 1.0
        phi[..., 1:6] = F[:, :, self._f_cols]
        phi[..., 6:9] = np.maximum(L[:, :, self._l_cols] - self._l_offs, 0.0)
        phi[..., 9] = np.maximum(p.phi_off - knee, 0.0) * (knee_v < 0.0)
        phi[..., 10] = np.maximum(bal, 0.0) * share
        phi[..., 11] = np.maximum(-bal, 0.0) * share
        phi[..., 12] = load[:, ::-1] * trailing
        phi[..., 13] = (lean - p.lean_ref)[:, None]
        u = np.where(stance[..., None], phi @ self._w_stance, phi @ self._w_swing)
        if self.lean_free is not None:  # the laws without the trunk-lean terms (labels)
            phi[..., LEAN_FEATURES] = 0.0
            v = np.where(stance[..., None], phi @ self._w_stance, phi @ self._w_swing)
            self.lean_free = np.clip(v.reshape(n, 2 * nm), PRE_ACTIVATION, 1.0)
        return np.clip(u.reshape(n, 2 * nm), PRE_ACTIVATION, 1.0)

    # ---- Controller protocol -----------------------------------------------------------
    def update(self, ctx: Context) -> np.ndarray:
        """The next 5 ms of excitations, from what was sensed at least 5 ms ago."""
        u = self._excitations(self.delay.read(self.period_steps))
        self.plan[:] = ctx.data.ctrl
        self.plan[:, self.act_ids] = u
        return self.plan

    def observe(self, rows: np.ndarray) -> None:
        """Store the block's sensed channels."""
        self.delay.push(self._channels(rows))

    def state(self) -> str:
        """The reflexes have one state (each leg's stance or swing is internal)."""
        return self._state
