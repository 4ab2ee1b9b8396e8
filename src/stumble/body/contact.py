"""Foot-ground contact: 96 penalty points per foot (SCA 2009 §4.1-4.2) or soft boxes.

SCA 2009 §4.2 computes ground reaction forces with a penalty law at each of 96 points
under each sole: f_n = k·depth + c·depth_rate, k = 3000 N/m, c = 10 N·s/m.

``points`` (default) applies exactly that law. The points are MuJoCo sites; each step
``PenaltyContact.apply`` reads their positions and velocities, computes the normal
force (never pulling: f_n >= 0) and a friction force, and writes the sum per foot
segment into ``data.xfrc_applied``. Friction is a stick-slip spring: a point that
touches down is anchored; the tangential force -k_t·(slip) - c_t·(slip rate) holds it
until it would exceed μ·f_n, and then the anchor slides with it (Coulomb). k_t and c_t
equal the normal k and c (our choice; SCA 2009 does not give a friction law).

Why not MuJoCo's negative ``solref`` = (-3000, -10) on spheres: that form sets a
reference *acceleration*, scaled by the contact's impedance and inverse inertia, so it
is not 3000 N/m per point; measured on a standing 70 kg body it gave a 4 Hz bounce and
about 6 mm of penetration where the paper's law gives 1.2 mm (m·g/(192·3000 N/m)).

``soft`` uses one box under the hind foot and one under the toes with MuJoCo's own
soft contact: robust and entirely in C, but not the paper's law.

The foot boxes also exist in ``points`` mode; there they collide only with obstacles.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from stumble.errors import InputError

MODES = ("points", "soft")
STIFFNESS_N_PER_M = 3000.0  # SCA 2009 §4.2, per contact point
DAMPING_NS_PER_M = 10.0  # SCA 2009 §4.2, per contact point
POINTS_ALONG, POINTS_ACROSS = 16, 6  # 96 points per foot, SCA 2009 §4.1
FRICTION = 0.8  # shoe sole on a dry floor; our choice (reported 0.6-1.0)
GRID_MARGIN_M = 0.005  # inset of the outer points from the sole's edge


def check_mode(mode: str) -> None:
    """Raise InputError unless ``mode`` names a foot-contact model."""
    if mode not in MODES:
        raise InputError(f"contact {mode!r} is not one of {', '.join(MODES)}")


def grid(heel_x: float, foot_len: float, foot_w: float) -> np.ndarray:
    """(96, 2) sole points (x, y) in the foot frame, heel to toe tip, inset by a margin."""
    xs = np.linspace(heel_x + GRID_MARGIN_M, heel_x + foot_len - GRID_MARGIN_M, POINTS_ALONG)
    ys = np.linspace(-0.5 * foot_w + GRID_MARGIN_M, 0.5 * foot_w - GRID_MARGIN_M,
                     POINTS_ACROSS)
    return np.array([(x, y) for x in xs for y in ys])


def add_foot(foot, toes, side: str, mode: str, heel_x: float, mtp: np.ndarray,
             foot_len: float, foot_w: float, ankle_h: float) -> list[str]:
    """Add the sole of one foot: two boxes and, in ``points`` mode, 96 sites.

    Returns the names of the 96 sole sites (penalty points, or markers in soft mode).
    ``toes`` is None for the planar model (toes lumped into the foot).
    """
    from stumble.body.build import FOOT_OBSTACLE, FOOT_RGBA, SEGMENT

    sole = -ankle_h
    box_conaff = FOOT_OBSTACLE | (SEGMENT if mode == "soft" else 0)
    if toes is None:
        parts = [(foot, (heel_x + 0.5 * foot_len, 0.0, 0.5 * sole),
                  (0.5 * foot_len, 0.5 * foot_w, 0.5 * ankle_h), f"foot_{side}_geom")]
    else:
        hind, toe_len, h = mtp[0] - heel_x, heel_x + foot_len - mtp[0], mtp[2] - sole
        parts = [(foot, (heel_x + 0.5 * hind, 0.0, 0.5 * sole),
                  (0.5 * hind, 0.5 * foot_w, 0.5 * ankle_h), f"foot_{side}_geom"),
                 (toes, (0.5 * toe_len, 0.0, -0.5 * h),
                  (0.5 * toe_len, 0.5 * foot_w, 0.5 * h), f"toes_{side}_geom")]
    for body, pos, half, name in parts:
        g = body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(map(float, pos)),
                          size=list(map(float, half)))
        g.contype, g.conaffinity, g.density = 0, box_conaff, 0.0
        g.rgba = list(FOOT_RGBA)
        g.friction = [FRICTION, 0.005, 0.0001]
    names = []  # the grid exists in both modes (in soft mode only as kinematic markers)
    for k, (x, y) in enumerate(grid(heel_x, foot_len, foot_w)):
        on_toes = toes is not None and x > mtp[0]
        body = toes if on_toes else foot
        pos = np.array([x, y, sole]) - (mtp if on_toes else 0.0)
        name = f"sole_{side}_{k:02d}"
        site = body.add_site(name=name, pos=list(map(float, pos)), size=[0.004, 0, 0])
        site.rgba = [0.9, 0.3, 0.2, 1.0]
        site.group = 3  # hidden in renders by default
        names.append(name)
    return names


@dataclass
class PenaltyContact:
    """The SCA 2009 §4.2 penalty law on the sole points of a model (stateful: anchors).

    Call ``apply(data)`` after ``mj_step1`` (positions and velocities of the current
    state) and before ``mj_step2``: it writes the feet's ground forces into
    ``data.xfrc_applied``. ``reset()`` forgets the friction anchors.
    """

    model: mujoco.MjModel
    site_ids: np.ndarray
    body_ids: np.ndarray  # body of each site
    bodies: np.ndarray  # distinct foot bodies
    k: float = STIFFNESS_N_PER_M
    c: float = DAMPING_NS_PER_M
    k_t: float = STIFFNESS_N_PER_M
    c_t: float = DAMPING_NS_PER_M
    mu: float = FRICTION
    ground_z: float = 0.0

    def __post_init__(self) -> None:
        self.root_ids = self.model.body_rootid[self.body_ids]
        self.slot = np.searchsorted(self.bodies, self.body_ids)
        self.reset()

    @classmethod
    def for_body(cls, body, **kwargs) -> PenaltyContact:
        """The penalty contact of a built ``stumble.body.Body`` (its 192 sole points)."""
        m = body.model
        names = [n for v in body.foot_points.values() for n in v]
        sid = np.array([m.site(n).id for n in names])
        bid = m.site_bodyid[sid]
        return cls(m, sid, bid, np.unique(bid), **kwargs)

    def reset(self) -> None:
        """Forget all friction anchors (every point free)."""
        n = len(self.site_ids)
        self.anchor = np.zeros((n, 2))
        self.stuck = np.zeros(n, dtype=bool)
        self.force = np.zeros((n, 3))

    def point_state(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """World positions and velocities (n, 3) of the sole points."""
        p = data.site_xpos[self.site_ids]
        cv = data.cvel[self.body_ids]
        r = p - data.subtree_com[self.root_ids]
        return p, cv[:, 3:] + np.cross(cv[:, :3], r)

    def apply(self, data: mujoco.MjData) -> np.ndarray:
        """Write the feet's ground forces into ``data.xfrc_applied``; returns (n, 3) forces."""
        p, v = self.point_state(data)
        depth = self.ground_z - p[:, 2]
        touching = depth > 0.0
        fn = np.where(touching, self.k * depth - self.c * v[:, 2], 0.0)
        fn = np.maximum(fn, 0.0)
        # friction: anchor new contacts, spring-damper to the anchor, slide at mu*fn
        new = touching & ~self.stuck
        self.anchor[new] = p[new, :2]
        self.stuck = touching
        slip = p[:, :2] - self.anchor
        ft = -self.k_t * slip - self.c_t * v[:, :2]
        mag = np.linalg.norm(ft, axis=1)
        limit = self.mu * fn
        over = mag > limit
        if over.any():
            scale = np.where(over, limit / np.maximum(mag, 1e-12), 1.0)
            ft *= scale[:, None]
            # slide the anchor so that the spring alone would give the limit force
            self.anchor[over] = p[over, :2] + (ft[over] + self.c_t * v[over, :2]) / self.k_t
        ft[~touching] = 0.0
        f = self.force
        f[:, :2], f[:, 2] = ft, fn
        torque = np.cross(p - data.xipos[self.body_ids], f)
        out = np.zeros((len(self.bodies), 6))
        np.add.at(out, self.slot, np.hstack([f, torque]))
        data.xfrc_applied[self.bodies] = out
        return f
