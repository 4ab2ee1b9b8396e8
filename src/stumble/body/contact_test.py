"""Foot contact: the SCA 2009 §4.2 penalty law, as 96 points per foot (the reference)
and lumped (the default)."""

import mujoco
import numpy as np
import pytest

from stumble.body import anthropometry as anth
from stumble.body import build
from stumble.body.contact import (
    POINTS_ACROSS,
    STIFFNESS_N_PER_M,
    PenaltyContact,
    grid,
    lump_axis,
    lumped_grid,
)


def _statue(planar: bool, mass_kg: float, contact: str):
    """A rigid standing body (stiff joint springs, no actuation), CoM over the sole centroid."""
    body = build(planar=planar, mass_kg=mass_kg, contact=contact)
    m, d = body.model, mujoco.MjData(body.model)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ACTUATION)
    lean = np.radians(4.5)  # lean forward at the ankles: CoM above the middle of the sole
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and m.jnt_bodyid[j] != 1:
            m.jnt_stiffness[j], m.dof_damping[m.jnt_dofadr[j]] = 2e4, 300.0
    for s in "rl":
        adr = m.jnt_qposadr[m.joint(f"ankle_angle_{s}").id]
        m.qpos_spring[adr] = d.qpos[adr] = lean
    if planar:
        d.qpos[2] = -lean
    else:
        d.qpos[3:7] = [np.cos(lean / 2), 0.0, np.sin(lean / 2), 0.0]  # pitch forward (about +y)
    sites = np.array([m.site(n).id for v in body.foot_points.values() for n in v])
    mujoco.mj_forward(m, d)
    d.qpos[1 if planar else 2] -= d.site_xpos[sites][:, 2].min() - 0.0005
    return body, m, d, sites


def _run(body, m, d, steps: int, record=None):
    """Step physics; the penalty mode applies its forces between mj_step1 and mj_step2."""
    penalty = PenaltyContact.for_body(body) if body.contact == "penalty" else None
    for k in range(steps):
        if penalty:
            mujoco.mj_step1(m, d)
            f = penalty.apply(d)
            mujoco.mj_step2(m, d)
            fz = f[:, 2].sum()
        else:
            mujoco.mj_step(m, d)
            fz = sum(_normal_force(m, d, i) for i in range(d.ncon))
        if record is not None:
            record(k, fz)


def _normal_force(m, d, i):
    f = np.zeros(6)
    mujoco.mj_contactForce(m, d, i, f)
    return f[0]


def test_each_foot_has_96_points_on_foot_and_toes():
    body = build(contact="points")
    assert {k: len(v) for k, v in body.foot_points.items()} == {"r": 96, "l": 96}
    m = body.model
    on_toes = sum(m.site_bodyid[m.site(n).id] == m.body("toes_r").id for n in body.foot_points["r"])
    assert 0 < on_toes < 96
    assert _sole_pairs(m) == 192  # one floor pair per point sphere


def _sole_pairs(m) -> int:
    """The floor-sphere pairs (the model's other pairs: segments and foot boxes with the
    floor and obstacle)."""
    return int((m.geom_type[m.pair_geom2] == mujoco.mjtGeom.mjGEOM_SPHERE).sum())


def test_lumped_is_the_default_and_has_few_pairs():
    assert build().contact == "lumped"
    assert _sole_pairs(build().model) == 24  # 3D: 2 × 3 along × 2 across per foot segment
    assert _sole_pairs(build(planar=True).model) == 32  # planar: one row of 16 per foot


def _moments(x: np.ndarray, w: np.ndarray) -> tuple[float, float, float]:
    total = w.sum()
    mid = (w * x).sum() / total
    return float(total), float(mid), float((w * (x - mid) ** 2).sum())


def test_lump_axis_keeps_total_centroid_and_second_moment():
    ref = np.linspace(0.0, 0.19, 12)
    for n in (2, 3, 5):  # (one point keeps the total and centroid only)
        x, w = lump_axis(ref, n)
        assert _moments(x, w) == pytest.approx(_moments(ref, np.ones(12)), rel=1e-12)
        assert np.all(w > 0)
    x, _ = lump_axis(ref, 3)
    assert x[0] == ref[0] and x[-1] == ref[-1]  # the edges stay where the sole ends


def test_lumped_sole_keeps_each_segments_stiffness_and_moments():
    """Per segment (hind foot, toes): total stiffness, centroid and the pitch and roll
    second moments of the 96-point grid (SCA 2009 §4.1), hence its force and moment."""
    length = anth.segment_length("foot", 1.75, "male")
    heel, width = -anth.HEEL_BEHIND_ANKLE_FOOT * length, anth.FOOT_WIDTH_H * 1.75
    mtp = heel + anth.MTP_FROM_HEEL_FOOT * length
    ref = grid(heel, length, width)
    pts, w = lumped_grid(heel, length, width, mtp)
    assert w.sum() == pytest.approx(96.0)
    for part_ref, part in ((ref[:, 0] <= mtp, pts[:, 0] <= mtp), (ref[:, 0] > mtp,
                                                                  pts[:, 0] > mtp)):
        for axis in (0, 1):
            assert _moments(pts[part, axis], w[part]) == pytest.approx(
                _moments(ref[part_ref, axis], np.ones(part_ref.sum())), rel=1e-9, abs=1e-12)
    row, w_row = lumped_grid(heel, length, width, None)  # planar: one row, exact columns
    assert np.allclose(row[:, 0], np.unique(ref[:, 0])) and np.all(w_row == POINTS_ACROSS)


@pytest.mark.parametrize("contact", ["lumped", "points", "penalty"])
@pytest.mark.parametrize(("planar", "mass"), [(False, 70.0), (True, 70.0), (False, 100.0)])
def test_standing_body_settles_at_the_papers_static_penetration(contact, planar, mass):
    body, m, d, sites = _statue(planar, mass, contact)
    fz, depth = [], []

    def record(k, f):
        if k >= 1000:
            z = d.site_xpos[sites][:, 2]
            fz.append(f)
            depth.append(-z[z < 0].mean())

    _run(body, m, d, 1500, record)
    weight = m.body_mass.sum() * 9.81
    assert np.mean(fz) == pytest.approx(weight, rel=0.02)
    expected = weight / (192 * STIFFNESS_N_PER_M)  # 1.19 mm for 70 kg (SCA 2009 §4.2 law)
    assert np.mean(depth) == pytest.approx(expected, rel=0.05)
    assert np.all(np.isfinite(d.qpos))


def _bounce(contact: str):
    """Pelvis height over 0.6 s after a 0.5 mm drop, and the dominant frequency."""
    body, m, d, _ = _statue(False, 70.0, contact)
    z = []
    _run(body, m, d, 600, lambda k, f: z.append(d.qpos[2]))
    z = np.array(z) - np.mean(z)
    spectrum = np.abs(np.fft.rfft(z))
    return z, np.fft.rfftfreq(len(z), m.opt.timestep)[1 + np.argmax(spectrum[1:])]


@pytest.mark.parametrize("contact", ["lumped", "points"])
def test_mujoco_contacts_bounce_like_the_explicit_penalty_law(contact):
    z_pts, f_pts = _bounce(contact)
    z_pen, f_pen = _bounce("penalty")
    # k = 3000 N/m on 192 points under 70 kg: sqrt(576000/70)/2π = 14.4 Hz (joints add some give)
    assert f_pts == pytest.approx(f_pen, rel=0.1)
    assert 10.0 < f_pen < 16.0
    assert np.ptp(z_pts) == pytest.approx(np.ptp(z_pen), rel=0.15)


def test_penalty_contact_never_pulls_and_friction_is_bounded():
    body, m, d, _ = _statue(False, 70.0, "penalty")
    d.qvel[0] = 0.5  # push the body forward: the feet must not slide faster than mu allows
    contact = PenaltyContact.for_body(body)
    for _ in range(300):
        mujoco.mj_step1(m, d)
        f = contact.apply(d)
        mujoco.mj_step2(m, d)
        assert np.all(f[:, 2] >= 0.0)
        assert np.all(np.linalg.norm(f[:, :2], axis=1) <= contact.mu * f[:, 2] + 1e-9)


@pytest.mark.parametrize("contact", ["lumped", "points"])
def test_points_hold_the_feet_under_a_push(contact):
    body, m, d, sites = _statue(False, 70.0, contact)
    _run(body, m, d, 200)
    heel = d.site_xpos[sites[0], :2].copy()
    d.qvel[0] = 0.3  # the body rocks forward; stuck feet do not slide
    _run(body, m, d, 300)
    assert np.linalg.norm(d.site_xpos[sites[0], :2] - heel) < 0.003


def test_soft_mode_has_boxes_that_touch_the_floor():
    body = build(contact="soft")
    m = body.model
    g, floor = m.geom("foot_r_geom").id, m.geom("floor").id
    # no sole spheres: the boxes meet the floor through a pair of their own
    assert not (m.geom_type[m.pair_geom2] == mujoco.mjtGeom.mjGEOM_SPHERE).any()
    assert m.pair("floor_foot_r_geom").geom1 == floor and m.pair("floor_foot_r_geom").geom2 == g
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    d.qpos[2] -= 0.01
    mujoco.mj_forward(m, d)
    assert d.ncon > 0


def test_lumped_feet_carry_the_reference_ground_force_through_a_trip():
    """Vertical ground force per foot over the first second of an elevating force trip,
    ``lumped`` against the 96-point reference (issue 10: r >= 0.95)."""
    from stumble.pipeline import simulate_trip
    from stumble.trip import Scenario

    recs = [simulate_trip(Scenario(swing_fraction=0.2, contact=c,
                                   duration_after_trip_s=1.0)).recording
            for c in ("lumped", "points")]
    n = min(len(r.time_s) for r in recs)
    for side in range(2):
        a, b = (r.foot_force[:n, side] for r in recs)
        assert np.corrcoef(a, b)[0, 1] >= 0.95
        assert abs(a.max() - b.max()) <= 0.1 * b.max()


@pytest.mark.parametrize("contact", ["lumped", "soft"])
def test_planar_markers_share_a_site_across_and_keep_x_and_z_to_the_bit(contact):
    """Planar ``lumped`` and ``soft``: 22 sole sites a foot stand for the 96 points; every
    point's x and z match the full grid's (``points`` mode) to the bit in any pose."""
    from stumble.body.sensors import CORNER_SITES

    lean, full = build(planar=True, contact=contact), build(planar=True, contact="points")
    assert lean.model.nsite == 2 * 22 + 1 and full.model.nsite == 2 * 96 + 1
    rng = np.random.default_rng(3)
    d_lean, d_full = mujoco.MjData(lean.model), mujoco.MjData(full.model)
    for _ in range(20):
        q = rng.uniform(-0.6, 0.6, lean.model.nq)
        for b, d in ((lean, d_lean), (full, d_full)):
            d.qpos[:] = q
            mujoco.mj_kinematics(b.model, d)
        for side in ("r", "l"):
            ids = [[b.model.site(n).id for n in b.foot_points[side]] for b in (lean, full)]
            a, f = d_lean.site_xpos[ids[0]], d_full.site_xpos[ids[1]]
            assert np.array_equal(a[:, [0, 2]], f[:, [0, 2]])
            own = sorted(CORNER_SITES + tuple(range(90, 96)))  # their y is read too
            assert np.array_equal(a[own], f[own])
            assert not np.array_equal(a[:, 1], f[:, 1])  # shared: the others' y is not
