"""Foot-ground contact: SCA 2009 §4.1-4.2's penalty law, lumped (default) or at its 96 points.

SCA 2009 §4.2 computes ground reaction forces with a penalty law at each of 96 points
under each sole: f_n = k·depth + c·depth_rate, k = 3000 N/m, c = 10 N·s/m.

Four modes:

``lumped`` (default): the same law on a few points that carry the 96 points' stiffness
and damping (``lumped_grid``): on the planar model one row of 16 along the sole, each
with its six-point column's 6 x 3000 N/m and 6 x 10 N·s/m (in the sagittal plane exactly
the 96-point law); on the 3D model 3 x 2 per foot segment (hind foot, toes), weighted so
that each segment keeps its total stiffness, centroid and second moments (pitch and roll
stiffness). Resolved as ``points`` below, with each sphere's ``solref`` scaled by its
weight. 12 contacts a foot instead of 96: a 3D trip steps about 4x faster
(docs/models.md "Foot contact"); trip outcomes agree with ``points`` (docs/trips.md "Trips").

``points`` (the reference): a small sphere at each point, resolved by MuJoCo in C through
one contact pair per sphere and floor, with *calibrated* direct ``solref``. MuJoCo's
soft contact drives the contact acceleration toward aref = -B·v - K·d·pos with
regularisation R = (1-d)/d·A (A the contact's diagonal inverse mass, d the impedance,
K = -solref[0]/d², B = -solref[1]/d; engine_core_constraint.c). At rest R·f = aref
exactly, so solref = (-k(1-d)A, -c(1-d)A) gives f = k·depth - c·(normal velocity),
the paper's law; with a small impedance d (``IMPEDANCE``) R ≫ A and the same holds
in motion to within about d/(1-d). Friction: an elliptic Coulomb cone (μ =
``FRICTION``) whose tangential rows are made nearly hard (``IMPRATIO``: their R is the
normal's / 1000), so a point sticks inside the cone and slides on its edge, solved
implicitly by MuJoCo (a stiff explicit friction on 96 points per foot is unstable at
1 ms). Checked against ``penalty`` by
the static penetration and the bounce of a standing body (contact_test.py).
Plain (-3000, -10) would *not* be the law: it sets an acceleration, and on a standing
body it gave about 6 mm of penetration and a 4 Hz bounce instead of 1.2 mm.

``penalty``: the same law computed explicitly in Python each step
(``PenaltyContact.apply`` between ``mj_step1`` and ``mj_step2``), with a stick-slip
spring friction. Exact by construction; the reference for ``points``, about 5× slower.

``soft``: one box under the hind foot and one under the toes with MuJoCo's default
soft contact. Robust and fast, not the paper's law.

In every mode the 96 points also exist as sites (kinematic markers for playback and
gait events), and the foot boxes collide with obstacles. On the planar model in the
``lumped`` and ``soft`` modes, where no force acts at them, the six points across a
column share one site (``MARKERS_PLANAR``): in the sagittal plane they have the same x
and z to the bit, and MuJoCo poses every site every step (about 6 % of the planar
step's time for the 148 sites saved).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from stumble.errors import InputError

MODES = ("lumped", "points", "penalty", "soft")
DEFAULT_MODE = "lumped"
STIFFNESS_N_PER_M = 3000.0  # SCA 2009 §4.2, per contact point
DAMPING_NS_PER_M = 10.0  # SCA 2009 §4.2, per contact point
POINTS_ALONG, POINTS_ACROSS = 16, 6  # 96 points per foot, SCA 2009 §4.1
# ``lumped`` (3D): points per foot segment along the sole (hind foot, toes) and across it
LUMPED_ALONG_3D = (3, 3)
LUMPED_ACROSS_3D = 2
FRICTION = 0.8  # shoe sole on a dry floor; our choice (reported 0.6-1.0)
IMPEDANCE = 0.02  # solimp d of the point contacts: small, so MuJoCo acts as a penalty law
IMPRATIO = 1000.0  # friction rows 1000x less compliant than the normal: near-hard stick
# Newton solver tolerance (ours; MuJoCo's default 1e-8). 3D: on the 48-trip grid 1e-6
# gives the same strategy, variant and outcome in all 48 trips, and trips run about 15 %
# faster (docs/trips.md "Trips"); 1e-5 too; 20 solver iterations instead of 100 changed 11.
# Planar: the shipped GH2010 walker (fitted at 1e-8) still walks 20 s, its speed
# 0.9989 -> 0.9997 m/s, stance 0.6092 -> 0.6086, knee RMSE 13.900 -> 13.906 deg, and both
# 45-trip strategy maps are unchanged.
SOLVER_TOLERANCE = 1e-6
STICK_RATE_PER_S = 500.0  # friction reference a_t = -B·v_t: sliding stops in ~2 ms
SPHERE_RADIUS_M = 0.004
GRID_MARGIN_M = 0.005  # inset of the outer points from the sole's edge
# The planar model's sole markers (``lumped``, ``soft``): the grid's points (16 along ×
# 6 across, heel first) that are sites of their own; every other point names the site of
# the first point of its column, which has the same x and z in the sagittal plane. The
# corners (``sensors.CORNER_SITES``) and the toe row (the trip's force point, the state
# machines' toe) keep their own: their y is read (ours; speed, bit for bit the same
# motion: ``contact_test``)
MARKERS_PLANAR = frozenset({*range(0, POINTS_ALONG * POINTS_ACROSS, POINTS_ACROSS),
                            POINTS_ACROSS - 1,
                            *range((POINTS_ALONG - 1) * POINTS_ACROSS,
                                   POINTS_ALONG * POINTS_ACROSS)})


def check_mode(mode: str) -> None:
    """Raise InputError unless ``mode`` names a foot-contact model."""
    if mode not in MODES:
        raise InputError(f"contact {mode!r} is not one of {', '.join(MODES)}")


def _axes(heel_x: float, foot_len: float, foot_w: float) -> tuple[np.ndarray, np.ndarray]:
    """The reference grid's 16 column x and 6 row y positions (m, foot frame)."""
    xs = np.linspace(heel_x + GRID_MARGIN_M, heel_x + foot_len - GRID_MARGIN_M, POINTS_ALONG)
    ys = np.linspace(-0.5 * foot_w + GRID_MARGIN_M, 0.5 * foot_w - GRID_MARGIN_M,
                     POINTS_ACROSS)
    return xs, ys


def grid(heel_x: float, foot_len: float, foot_w: float) -> np.ndarray:
    """(96, 2) sole points (x, y) in the foot frame, heel to toe tip, inset by a margin."""
    xs, ys = _axes(heel_x, foot_len, foot_w)
    return np.array([(x, y) for x in xs for y in ys])


def lump_axis(ref: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` positions and weights (in reference points) standing for the equally
    weighted positions ``ref``: same total, centroid and second moment about it.

    n = 1: the centroid (no second moment). n = 2: centroid ± the spread (a weight of
    half each). n ≥ 3: equally spaced from the first to the last reference position (the
    sole's edges stay where they are), with the symmetric weights closest to equal that
    match the second moment.
    """
    ref = np.asarray(ref, dtype=float)
    mid, total = float(ref.mean()), float(len(ref))
    m2 = float(np.sum((ref - mid) ** 2))
    if n == 1:
        return np.array([mid]), np.array([total])
    if n == 2:
        s = np.sqrt(m2 / total)
        return np.array([mid - s, mid + s]), np.array([0.5 * total, 0.5 * total])
    x = np.linspace(ref[0], ref[-1], n)
    a = np.vstack([np.ones(n), (x - mid) ** 2])
    w0 = np.full(n, total / n)
    w = w0 + a.T @ np.linalg.solve(a @ a.T, np.array([total, m2]) - a @ w0)
    if np.any(w <= 0.0):
        raise ValueError(f"no positive weights for {n} points over {len(ref)}")
    return x, w


def lumped_grid(heel_x: float, foot_len: float, foot_w: float, mtp_x: float | None,
                ) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) sole points (x, y) in the foot frame and the reference points each stands
    for (n,): the ``lumped`` contact.

    ``mtp_x`` None (planar model, toes lumped into the foot): one row along the sole,
    each point carrying its six-point column. In the sagittal plane this *is* the
    96-point law. Otherwise the hind foot's and the toes' columns are lumped separately
    (``LUMPED_ALONG_3D``), and so are the rows (``LUMPED_ACROSS_3D``): each segment keeps
    its total stiffness and damping, its centroid, and its pitch and roll stiffness about
    it (the second moments), so the force and moment of a flat-loaded sole are the
    reference's.
    """
    xs, ys = _axes(heel_x, foot_len, foot_w)
    if mtp_x is None:
        return np.column_stack([xs, np.zeros_like(xs)]), np.full(len(xs), float(len(ys)))
    ly, wy = lump_axis(ys, LUMPED_ACROSS_3D)
    pts, weights = [], []
    for part, n in zip((xs[xs <= mtp_x], xs[xs > mtp_x]), LUMPED_ALONG_3D, strict=True):
        lx, wx = lump_axis(part, n)
        for x, a in zip(lx, wx, strict=True):
            for y, b in zip(ly, wy, strict=True):
                pts.append((x, y))
                weights.append(a * b)
    return np.array(pts), np.array(weights)


def add_foot(spec: mujoco.MjSpec, foot, toes, side: str, mode: str, heel_x: float,
             mtp: np.ndarray, foot_len: float, foot_w: float, ankle_h: float,
             ) -> tuple[list[str], list[float]]:
    """Add the sole of one foot: its boxes (one on the planar model, hind foot and toes
    in 3D), its 96 points' sites and the contact spheres of the mode.

    Returns the names of the 96 points' sites (planar ``lumped`` and ``soft``: 22 sites,
    the other points naming their column's first, ``MARKERS_PLANAR``) and, per floor
    pair added (in order), the number of reference points its sphere stands for
    (``points``: 1 each; ``lumped``: see ``lumped_grid``; ``penalty``/``soft``: none).
    Sphere ``sole_r_07`` (``points``) has geom ``sole_r_07_geom`` and pair
    ``sole_r_07_floor``; ``lumped`` spheres are ``lump_r_03_geom``. ``toes`` is None for
    the planar model (toes lumped into the foot).
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

    def place(x: float, y: float) -> tuple[object, np.ndarray]:
        on_toes = toes is not None and x > mtp[0]
        return (toes if on_toes else foot), np.array([x, y, sole]) - (mtp if on_toes else 0.0)

    def sphere(body, pos: np.ndarray, name: str) -> None:
        g = body.add_geom(name=f"{name}_geom", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                          pos=[float(pos[0]), float(pos[1]), float(pos[2] + SPHERE_RADIUS_M)],
                          size=[SPHERE_RADIUS_M, 0, 0])
        g.contype, g.conaffinity, g.density, g.group = 0, 0, 0.0, 3
        spec.add_pair(name=f"{name}_floor", geomname1="floor", geomname2=f"{name}_geom",
                      condim=3)

    names, weights = [], []  # the grid exists in every mode (as kinematic markers)
    shared = toes is None and mode in ("lumped", "soft")  # planar: ``MARKERS_PLANAR``
    for k, (x, y) in enumerate(grid(heel_x, foot_len, foot_w)):
        body, pos = place(x, y)
        name = f"sole_{side}_{k:02d}"
        if shared and k not in MARKERS_PLANAR:
            names.append(f"sole_{side}_{k - k % POINTS_ACROSS:02d}")
            continue
        site = body.add_site(name=name, pos=list(map(float, pos)), size=[0.004, 0, 0])
        site.rgba = [0.9, 0.3, 0.2, 1.0]
        site.group = 3  # hidden in renders by default
        names.append(name)
        if mode == "points":
            sphere(body, pos, name)
            weights.append(1.0)
    if mode == "lumped":
        pts, w = lumped_grid(heel_x, foot_len, foot_w, None if toes is None else mtp[0])
        for k, ((x, y), n) in enumerate(zip(pts, w, strict=True)):
            sphere(*place(x, y), f"lump_{side}_{k:02d}")
            weights.append(float(n))
    return names, weights


def sole_positions(model: mujoco.MjModel, data: mujoco.MjData, names: list[str],
                   planar: bool) -> np.ndarray:
    """World positions (96, 3), m, of one foot's sole points (``names``: its
    ``Body.foot_points``) in ``data``'s pose; on the planar model a point whose column
    shares a site (``MARKERS_PLANAR``) takes its y across from the toe row's own site,
    the same in every column of the planar foot to the bit."""
    ids = [model.site(n).id for n in names]
    pts = data.site_xpos[ids].copy()
    if planar:
        pts[:, 1] = np.tile(pts[-POINTS_ACROSS:, 1], len(ids) // POINTS_ACROSS)
    return pts


def configure(model: mujoco.MjModel, weights: np.ndarray | None = None) -> None:
    """Calibrate every floor-sphere pair of a compiled model to the SCA 2009 §4.2 law:
    the i-th such pair (in the model's order) carries ``weights[i]`` reference points'
    stiffness and damping (default 1). The model's other pairs (segments and feet with
    the floor and obstacle, ``build._world_pairs``) keep MuJoCo's own contact law."""
    d = IMPEDANCE
    spheres = [i for i in range(model.npair)
               if model.geom_type[model.pair_geom2[i]] == mujoco.mjtGeom.mjGEOM_SPHERE]
    w = np.ones(len(spheres)) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (len(spheres),):
        raise ValueError(f"{len(w)} contact weights for {len(spheres)} sole pairs")
    for j, i in enumerate(spheres):
        a = float(model.body_invweight0[model.geom_bodyid[model.pair_geom2[i]], 0])
        k, c = STIFFNESS_N_PER_M * w[j], DAMPING_NS_PER_M * w[j]
        model.pair_solimp[i] = (d, d, 0.001, 0.5, 2.0)
        model.pair_solref[i] = (-k * (1 - d) * a, -c * (1 - d) * a)
        model.pair_solreffriction[i] = (0.0, -STICK_RATE_PER_S * d)  # direct: B = -s1/d
        model.pair_friction[i] = (FRICTION, FRICTION, 0.005, 1e-4, 1e-4)
        model.pair_margin[i] = 0.0
        model.pair_gap[i] = 0.0


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


def rest_support_foot(m: mujoco.MjModel, d: mujoco.MjData, planar: bool) -> None:
    """SCA 2009 §4.2: the support foot on the ground, at the penalty law's static depth
    under the body's weight on one foot (96 points)."""
    height = m.jnt_qposadr[m.joint("pelvis_ty").id] if planar else 2  # z of the root
    d.qpos[height] -= m.body_mass.sum() * 9.81 / (96 * STIFFNESS_N_PER_M)
