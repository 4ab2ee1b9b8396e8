"""PD servos on the model's position actuators: τ = k_p(θ_d − θ) − k_d θ̇ (SCA 2009 eq. 1).

Each internal DOF has a MuJoCo position actuator (``stumble.body.build``), so the servo
law runs in C at every physics step; a controller only changes targets and gains.
"""

from __future__ import annotations

import mujoco
import numpy as np

from stumble.body import Body
from stumble.body.build import KD_OVER_KP_S


class ServoBank:
    """Targets (rad) and gains (N·m/rad) of every joint servo of a model, by joint name."""

    def __init__(self, body: Body, kd_over_kp_s: float = KD_OVER_KP_S):
        m = body.model
        self.model = m
        self.names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i)
                      for i in range(m.nu)]
        self.index = {n: i for i, n in enumerate(self.names)}
        self.qadr = np.array([m.jnt_qposadr[m.actuator_trnid[i, 0]] for i in range(m.nu)])
        self.vadr = np.array([m.jnt_dofadr[m.actuator_trnid[i, 0]] for i in range(m.nu)])
        self.kd_over_kp = kd_over_kp_s
        self.kp = m.actuator_gainprm[:, 0].copy()

    def ids(self, names) -> np.ndarray:
        """Actuator indices of joint names."""
        return np.array([self.index[n] for n in names], dtype=int)

    def angles(self, data: mujoco.MjData) -> np.ndarray:
        """Current joint angles (rad) in actuator order."""
        return data.qpos[self.qadr]

    def set_gains(self, kp: np.ndarray, ids: np.ndarray | None = None) -> None:
        """Set k_p (and k_d = ratio · k_p) for some actuators (all if ``ids`` is None)."""
        sel = slice(None) if ids is None else ids
        self.kp[sel] = kp
        m = self.model
        m.actuator_gainprm[sel, 0] = self.kp[sel]
        m.actuator_biasprm[sel, 1] = -self.kp[sel]
        m.actuator_biasprm[sel, 2] = -self.kd_over_kp * self.kp[sel]
