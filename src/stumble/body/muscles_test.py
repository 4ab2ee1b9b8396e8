"""The musculoskeletal planar body: seed 003 eq. 1 as MuJoCo muscle actuators."""

import mujoco
import numpy as np
import pytest

from stumble.body import build
from stumble.body import muscles as M
from stumble.errors import InputError


@pytest.fixture(scope="module")
def body():
    return build(planar=True, actuation="muscles")


def test_fourteen_muscles_and_a_lumbar_servo(body):
    m = body.model
    names = [m.actuator(i).name for i in range(m.nu)]
    assert m.nu == 15 and m.na == 14 and m.nv == 10
    assert names[0] == "lumbar_extension"
    assert {f"{n}_{s}" for n in M.MUSCLE_NAMES for s in "rl"} == set(names[1:])


def test_muscles_need_the_planar_model():
    with pytest.raises(InputError, match="planar"):
        build(planar=False, actuation="muscles")
    with pytest.raises(InputError, match="actuation"):
        build(planar=True, actuation="springs")


def test_mujoco_force_is_eq1_with_our_curves(body):
    """f = a·F_l(l)·F_v(v)·F_max + passive, at random states, for every muscle."""
    m = body.model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    for _ in range(5):
        d.qpos[3:] = rng.uniform(-0.6, 0.3, m.nq - 3)
        d.qvel[:] = rng.normal(0.0, 2.0, m.nv)
        a = rng.uniform(0.0, 1.0, m.na)
        d.act[:] = a
        mujoco.mj_forward(m, d)
        for g in body.muscles:
            i = m.actuator(g.name).id
            ours = M.muscle_force_n(g, a[m.actuator_actadr[i]], d.actuator_length[i],
                                    d.actuator_velocity[i])
            assert -d.actuator_force[i] == pytest.approx(float(ours), rel=1e-9, abs=1e-9)


def test_curves_follow_geyer_and_herr():
    x = np.linspace(0.4, 1.6, 121)
    assert np.abs(M.force_length(x) - M.geyer_force_length(x)).max() < 0.12
    assert M.force_length(1.0) == 1.0 and M.force_velocity(0.0) == 1.0
    assert M.force_velocity(-1.0) == 0.0 and M.force_velocity(1.0) == M.N_ECC
    lo, hi = M.fit_mujoco_curves()
    assert lo == pytest.approx(M.L_MIN, abs=0.01) and hi == pytest.approx(M.L_MAX, abs=0.01)


def test_muscles_pull_the_right_way(body):
    """Fully active SOL plantarflexes, TA dorsiflexes, HAMS extends hip and flexes knee."""
    m = body.model
    expect = {"SOL_r": {"ankle_angle_r": -1}, "TA_r": {"ankle_angle_r": +1},
              "HAMS_r": {"hip_flexion_r": -1, "knee_angle_r": -1},
              "RF_r": {"hip_flexion_r": +1, "knee_angle_r": +1},
              "GAS_r": {"knee_angle_r": -1, "ankle_angle_r": -1}}
    for name, joints in expect.items():
        d = mujoco.MjData(m)
        d.qpos[m.joint("knee_angle_r").qposadr[0]] = -0.3
        d.act[m.actuator_actadr[m.actuator(name).id]] = 1.0
        mujoco.mj_forward(m, d)
        for j, sign in joints.items():
            tau = d.qfrc_actuator[m.joint(j).dofadr[0]]
            assert np.sign(tau) == sign, (name, j, tau)


def test_optimal_length_at_geyers_reference_angle(body):
    """SOL is at l_opt at Geyer's φ_ref = 80° (ankle 10° dorsiflexed)."""
    m = body.model
    d = mujoco.MjData(m)
    d.qpos[m.joint("ankle_angle_l").qposadr[0]] = np.radians(10.0)
    mujoco.mj_forward(m, d)
    g = next(x for x in body.muscles if x.name == "SOL_l")
    assert M.normalised_length(g, d.actuator_length[m.actuator("SOL_l").id]) == \
        pytest.approx(1.0, abs=1e-9)


def test_force_scales_with_body_mass():
    light = build(planar=True, actuation="muscles", mass_kg=60.0)
    heavy = build(planar=True, actuation="muscles", mass_kg=90.0)
    i = light.model.actuator("VAS_r").id
    assert heavy.model.actuator_gainprm[i, 2] / light.model.actuator_gainprm[i, 2] == \
        pytest.approx(1.5)
    assert light.model.actuator_gainprm[i, 2] == pytest.approx(6000.0 * 60.0 / 80.0)
