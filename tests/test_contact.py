"""Foot contact: 96 points per foot with the SCA 2009 §4.2 penalty law."""

import mujoco
import numpy as np
import pytest

from stumble.body import build
from stumble.body.contact import STIFFNESS_N_PER_M, PenaltyContact


def _statue(planar: bool, mass_kg: float):
    """A rigid standing body (stiff joint springs, no actuation), CoM over the sole centroid."""
    body = build(planar=planar, mass_kg=mass_kg)
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
    contact = PenaltyContact.for_body(body)
    mujoco.mj_forward(m, d)
    d.qpos[1 if planar else 2] -= d.site_xpos[contact.site_ids][:, 2].min() - 0.0005
    return body, m, d, contact


def test_each_foot_has_96_points_on_foot_and_toes():
    body = build()
    assert {k: len(v) for k, v in body.foot_points.items()} == {"r": 96, "l": 96}
    m = body.model
    on_toes = sum(m.site_bodyid[m.site(n).id] == m.body("toes_r").id for n in body.foot_points["r"])
    assert 0 < on_toes < 96


@pytest.mark.parametrize(("planar", "mass"), [(False, 70.0), (True, 70.0), (False, 100.0)])
def test_standing_body_settles_at_the_papers_static_penetration(planar, mass):
    _, m, d, contact = _statue(planar, mass)
    fz, depth = [], []
    for k in range(1500):
        mujoco.mj_step1(m, d)
        f = contact.apply(d)
        mujoco.mj_step2(m, d)
        if k >= 1000:
            z = d.site_xpos[contact.site_ids][:, 2]
            fz.append(f[:, 2].sum())
            depth.append(-z[z < 0].mean())
    weight = m.body_mass.sum() * 9.81
    assert np.mean(fz) == pytest.approx(weight, rel=0.02)
    expected = weight / (192 * STIFFNESS_N_PER_M)  # 1.19 mm for 70 kg (SCA 2009 §4.2 law)
    assert np.mean(depth) == pytest.approx(expected, rel=0.15)
    assert np.all(np.isfinite(d.qpos))


def test_contact_never_pulls_and_friction_is_bounded():
    _, m, d, contact = _statue(False, 70.0)
    d.qvel[0] = 0.5  # push the body forward: the feet must not slide faster than mu allows
    for _ in range(300):
        mujoco.mj_step1(m, d)
        f = contact.apply(d)
        mujoco.mj_step2(m, d)
        assert np.all(f[:, 2] >= 0.0)
        assert np.all(np.linalg.norm(f[:, :2], axis=1) <= contact.mu * f[:, 2] + 1e-9)


def test_soft_mode_has_boxes_that_touch_the_floor():
    body = build(contact="soft")
    m = body.model
    g = m.geom("foot_r_geom").id
    assert m.geom_conaffinity[g] & m.geom_contype[m.geom("floor").id]
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    d.qpos[2] -= 0.01
    mujoco.mj_forward(m, d)
    assert d.ncon > 0
