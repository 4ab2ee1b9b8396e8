"""PD servos on the model's position actuators: τ = k_p(θ_d − θ) − k_d θ̇ (SCA 2009 eq. 1).

Each internal DOF has a MuJoCo position actuator (``stumble.body.build``), so the servo
law runs in C at every physics step; a controller only changes targets and gains.
"""

from __future__ import annotations

import mujoco
import numpy as np

from stumble.body import Body
from stumble.body.build import KD_OVER_KP_S, REFERENCE_BODY, body_scale

BODY_SCALINGS = ("dynamic", "none")


class ServoBank:
    """Targets (rad) and gains (N·m/rad) of every joint servo of a model, by joint name.

    Gains are given for the reference body (70 kg, 1.75 m). ``scaling`` dynamic (the
    default) writes k_p × m·h / (70 kg · 1.75 m) (``build.body_scale``) and k_d / k_p ×
    √(h / 1.75 m) to the model: under dynamic similarity a body h tall moves as the
    reference does in time units √(h/g), its joint moments scaled by m·h. ``none``: the
    gains as given, for every body (before).
    """

    def __init__(self, body: Body, kd_over_kp_s: float = KD_OVER_KP_S,
                 scaling: str = "dynamic"):
        if scaling not in BODY_SCALINGS:
            raise ValueError(f"body scaling {scaling!r} is not dynamic or none")
        dynamic = scaling == "dynamic"
        self.gain_scale = body_scale(body.mass_kg, body.height_m) if dynamic else 1.0
        time_scale = (body.height_m / REFERENCE_BODY[1]) ** 0.5 if dynamic else 1.0
        m = body.model
        self.model = m
        self.names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i)
                      for i in range(m.nu)]
        self.index = {n: i for i, n in enumerate(self.names)}
        self.qadr = np.array([m.jnt_qposadr[m.actuator_trnid[i, 0]] for i in range(m.nu)])
        self.vadr = np.array([m.jnt_dofadr[m.actuator_trnid[i, 0]] for i in range(m.nu)])
        self.kd_over_kp = kd_over_kp_s * time_scale
        self.kp = m.actuator_gainprm[:, 0].copy() / self.gain_scale

    def ids(self, names) -> np.ndarray:
        """Actuator indices of joint names."""
        return np.array([self.index[n] for n in names], dtype=int)

    def angles(self, data: mujoco.MjData) -> np.ndarray:
        """Current joint angles (rad) in actuator order."""
        return data.qpos[self.qadr]

    def set_gains(self, kp: np.ndarray, ids: np.ndarray | None = None) -> None:
        """Set k_p (reference body; and k_d = ratio · k_p) for some actuators (all if
        ``ids`` is None); the model gets them scaled to the body."""
        sel = slice(None) if ids is None else ids
        self.kp[sel] = kp
        m = self.model
        kp_body = self.gain_scale * self.kp[sel]
        m.actuator_gainprm[sel, 0] = kp_body
        m.actuator_biasprm[sel, 1] = -kp_body
        m.actuator_biasprm[sel, 2] = -self.kd_over_kp * kp_body
