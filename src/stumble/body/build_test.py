"""The human models: DOF counts, anthropometry, scaling and errors."""

import mujoco
import numpy as np
import pytest

from stumble.body import build
from stumble.body.anthropometry import mass_fraction
from stumble.body.joints import JOINTS_3D, hinge_names
from stumble.errors import InputError


def test_3d_model_has_16_joints_36_internal_dof_42_total():
    body = build()
    m = body.model
    assert sum(2 if j.sided else 1 for j in JOINTS_3D) == 16
    assert (m.nq, m.nv, m.nu) == (43, 42, 36)
    assert len(body.joints) == 36
    assert sorted(body.joints) == sorted(hinge_names())
    three = [j for j in JOINTS_3D if len(j.hinges) == 3]
    assert sorted(j.name for j in three) == ["chest", "hip", "neck", "shoulder"]
    # every joint's first hinge is its sagittal pitch
    for j in JOINTS_3D:
        assert "flexion" in j.hinges[0].name or j.hinges[0].name in (
            "lumbar_extension", "knee_angle", "ankle_angle", "mtp_angle", "wrist_flexion")


def test_planar_model_root_and_sagittal_joints():
    body = build(planar=True)
    assert (body.model.nq, body.model.nv) == (10, 10)
    assert body.describe()["root"] == ["pelvis_tx", "pelvis_ty", "pelvis_tilt"]
    assert body.joints == ["lumbar_extension", "hip_flexion_r", "knee_angle_r", "ankle_angle_r",
                           "hip_flexion_l", "knee_angle_l", "ankle_angle_l"]


@pytest.mark.parametrize("planar", [False, True])
@pytest.mark.parametrize(("mass", "height", "sex"), [(70.0, 1.75, "male"), (55.0, 1.60, "female"),
                                                      (95.0, 1.90, "male")])
def test_total_mass_and_segment_shares_follow_de_leva(planar, mass, height, sex):
    body = build(planar=planar, mass_kg=mass, height_m=height, sex=sex)
    assert body.model.body_mass.sum() == pytest.approx(mass, rel=1e-9)
    segs = body.segments
    thigh = segs["thigh_r"]
    assert thigh == pytest.approx(mass_fraction("thigh", sex) * mass)  # de Leva 1996
    assert segs["shank_l"] == pytest.approx(mass_fraction("shank", sex) * mass)


def test_height_scales_standing_height_and_segment_lengths():
    for h in (1.6, 1.75, 1.9):
        body = build(height_m=h)
        m, d = body.model, mujoco.MjData(body.model)
        mujoco.mj_forward(m, d)
        top = d.geom_xpos[m.geom("head_geom").id][2] + m.geom_size[m.geom("head_geom").id][0]
        sole = d.geom_xpos[m.geom("foot_r_geom").id][2] - m.geom_size[m.geom("foot_r_geom").id][2]
        # head sphere top at the stature within 3 cm (the skull is not a sphere)
        assert top - sole == pytest.approx(h, abs=0.03)
        knee = d.xpos[m.body("shank_r").id][2] - sole
        assert knee / h == pytest.approx(0.285, abs=0.02)  # Winter 2009 knee height 0.285 H


def test_female_segments_differ_from_male():
    f, mm = build(sex="female").segments, build(sex="male").segments
    assert f["thigh_r"] > mm["thigh_r"]  # de Leva: 14.78 % vs 14.16 %
    assert f["pelvis"] > mm["pelvis"]  # 12.47 % vs 11.17 %


def test_joint_ranges_are_human_and_in_radians():
    m = build().model
    knee = m.jnt_range[m.joint("knee_angle_r").id]
    assert np.degrees(knee) == pytest.approx([-135.0, 5.0])
    assert m.jnt_limited[m.joint("hip_flexion_l").id]


def test_left_axes_mirror_right():
    m = build().model
    for name in ("hip_adduction", "hip_rotation", "subtalar_angle"):
        r, left = m.jnt_axis[m.joint(f"{name}_r").id], m.jnt_axis[m.joint(f"{name}_l").id]
        assert np.allclose(left, [-r[0], r[1], -r[2]])
    assert np.allclose(m.jnt_axis[m.joint("knee_angle_l").id], [0, -1, 0])


@pytest.mark.parametrize(("kwargs", "word"), [
    ({"height_m": -1.75}, "height"), ({"height_m": 3.0}, "height"),
    ({"mass_kg": 0.0}, "mass"), ({"sex": "other"}, "sex"), ({"contact": "glue"}, "contact"),
])
def test_bad_person_raises_one_line_error(kwargs, word):
    with pytest.raises(InputError) as e:
        build(**kwargs)
    assert word in str(e.value) and "\n" not in str(e.value)


def test_build_keeps_compiled_models_but_hands_out_copies():
    """The same arguments give the same model (compiled once per process) as a new copy:
    changing one body's model or lists leaves the next one alone."""
    from stumble.body.build import compile_body

    a = build(planar=True, actuation="muscles", obstacle=(0.0, 0.1, 0.1, 0.14, 0.0))
    b = build(planar=True, actuation="muscles", obstacle=(0.0, 0.1, 0.1, 0.14, 0.0))
    assert a.model is not b.model and a.joints is not b.joints
    fresh = compile_body(planar=True, actuation="muscles",
                         obstacle=(0.0, 0.1, 0.1, 0.14, 0.0))
    for m in (a.model, b.model):
        assert m.nq == fresh.model.nq == 10
        assert np.array_equal(m.body_mass, fresh.model.body_mass)
        assert np.array_equal(m.geom_pos, fresh.model.geom_pos)
    a.model.geom_pos[a.model.geom("obstacle").id] = [5.0, 0.0, 0.05]
    a.joints.append("nothing")
    c = build(planar=True, actuation="muscles", obstacle=(0.0, 0.1, 0.1, 0.14, 0.0))
    assert np.array_equal(c.model.geom_pos, fresh.model.geom_pos)
    assert c.joints == fresh.joints
    d = mujoco.MjData(c.model)
    mujoco.mj_step(c.model, d)  # a copy steps like the original
    with pytest.raises(InputError, match="height"):
        build(height_m=-1.0)


FALL = (0.3, 0.1, 0.05, 1.0, 0.0)  # a wide box ahead: the body falls face down across it
UNDER_FOOT = (0.12, 0.03, 0.05, 0.14, -0.0851)  # a low box under the right forefoot


@pytest.mark.parametrize(("planar", "contact"), [(True, "lumped"), (True, "points"),
                                                 (True, "soft"), (False, "lumped"),
                                                 (False, "soft")])  # 3D points: slow
@pytest.mark.parametrize("scene", ["fall", "under_foot"])
def test_world_pairs_give_the_broad_phase_contacts_bit_for_bit(planar, contact, scene):
    """The explicit pairs (the default) and MuJoCo's broad phase over the bit masks make
    the same contacts, in the same order, with the same parameters, and the same motion
    to the bit: a body falling face down across an obstacle, and one standing with a
    forefoot on a low box (the foot's sole and box against the floor and the box in one
    step)."""
    from stumble.body.build import compile_body

    kw = dict(planar=planar, contact=contact, obstacle=FALL if scene == "fall" else UNDER_FOOT,
              **({"actuation": "muscles"} if planar else {}))
    pairs, masks = compile_body(**kw).model, compile_body(**kw, world_pairs=False).model
    assert pairs.npair > masks.npair and not pairs.geom_conaffinity.any()
    datas = [mujoco.MjData(m) for m in (pairs, masks)]
    if scene == "fall":
        for m, d in zip((pairs, masks), datas, strict=True):
            d.qpos[m.joint("pelvis_tx" if planar else "pelvis").qposadr[0]] += 0.2
            if planar:
                d.qpos[m.joint("pelvis_tilt").qposadr[0]] = -0.9  # far forward: a fall
            else:
                d.qpos[3:7] = (np.cos(0.45), 0.0, np.sin(0.45), 0.0)
    seen, both = set(), False
    foot, floor, box = (pairs.body("foot_r").id, pairs.geom("floor").id,
                        pairs.geom("obstacle").id)
    for _ in range(1500 if scene == "fall" else 400):
        for m, d in zip((pairs, masks), datas, strict=True):
            mujoco.mj_step(m, d)
        a, b = datas
        assert a.ncon == b.ncon
        for field in ("geom", "pos", "frame", "dist", "dim", "friction", "solref",
                      "solimp", "solreffriction", "includemargin"):
            assert np.array_equal(getattr(a.contact, field), getattr(b.contact, field)), field
        geoms = a.contact.geom
        seen |= set(geoms.ravel().tolist())
        on_foot = geoms[(pairs.geom_bodyid[geoms] == foot).any(axis=1)]
        both |= bool((on_foot == floor).any() and (on_foot == box).any())
    assert np.array_equal(a.qpos, b.qpos) and np.array_equal(a.qvel, b.qvel)
    if scene == "fall":  # segments touched the floor and the obstacle, not only the soles
        assert {floor, box, pairs.geom("torso_geom").id} <= seen, seen
    else:  # the right foot on the floor and on the box at once
        assert both, seen


def test_world_pairs_refuse_what_an_explicit_pair_cannot_copy():
    """``_world_pairs`` raises for geoms MuJoCo would mix inexactly, bodies that collide
    with each other and a body welded to the world; a jointed body's floor pair copies
    the larger friction."""
    import mujoco

    from stumble.body.build import _world_pairs

    def spec(solmix=1.0, body_masks=False, joint=True):
        s = mujoco.MjSpec()
        floor = s.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
                                     size=[1, 1, 0.1])
        floor.contype, floor.conaffinity = 1, 0
        for name in ("a", "b"):
            b = s.worldbody.add_body(name=name, pos=[0, 0, 1])
            if joint:
                b.add_freejoint()
            g = b.add_geom(name=f"{name}_geom", size=[0.1, 0, 0])
            g.contype, g.conaffinity = (1 if body_masks else 0), 1
            g.solmix, g.friction = solmix if name == "b" else 1.0, [1.2, 0.005, 0.0001]
        return s

    s = spec()
    _world_pairs(s)
    m = s.compile()
    assert m.npair == 2 and not m.geom_conaffinity.any()
    assert m.pair_friction[0, 0] == 1.2  # the larger of the floor's 1 and the geom's
    for bad, word in ((spec(solmix=2.0), "mix"), (spec(body_masks=True), "each other"),
                      (spec(joint=False), "welded")):
        with pytest.raises(ValueError, match=word):
            _world_pairs(bad)


def test_world_pairs_order_a_body_of_mixed_geom_types_as_mujoco_does():
    """A body with a capsule and a box landing on a world box: the pairs (ordered within
    the body by the geom of the lower type, as MuJoCo sorts) and the broad phase make the
    same contacts, in the same order, and the same motion."""
    import mujoco

    from stumble.body.build import _world_pairs

    def spec():
        s = mujoco.MjSpec()
        for name, typ, size, pos in (("floor", mujoco.mjtGeom.mjGEOM_PLANE, [2, 2, 0.1],
                                      [0, 0, 0]),
                                     ("box", mujoco.mjtGeom.mjGEOM_BOX, [0.5, 0.5, 0.1],
                                      [0, 0, 0.1])):
            g = s.worldbody.add_geom(name=name, type=typ, size=size, pos=pos)
            g.contype, g.conaffinity = 1, 0
        b = s.worldbody.add_body(name="b", pos=[0, 0, 0.3], euler=[0, 0.05, 0])
        b.add_freejoint()
        for name, typ, size, pos in (("b_cap", mujoco.mjtGeom.mjGEOM_CAPSULE, [0.04, 0.1, 0],
                                      [-0.05, 0, 0]),
                                     ("b_box", mujoco.mjtGeom.mjGEOM_BOX, [0.05, 0.05, 0.05],
                                      [0.1, 0, 0])):
            g = b.add_geom(name=name, type=typ, size=size, pos=pos)
            g.contype, g.conaffinity = 0, 1
        return s

    s = spec()
    _world_pairs(s)
    pairs, masks = s.compile(), spec().compile()
    names = [(pairs.geom(pairs.pair_geom1[i]).name, pairs.geom(pairs.pair_geom2[i]).name)
             for i in range(pairs.npair)]
    # geom ids: floor 0, box 1, b_cap 2, b_box 3. MuJoCo sorts a body pair's contacts by
    # (the geom of the lower type, the other): (0, 2), (0, 3), (1, 3) for box/b_box, and
    # (2, 1) for b_cap/box, a capsule's type being below a box's; world geom first would
    # put box/b_cap before box/b_box
    assert names == [("floor", "b_cap"), ("floor", "b_box"), ("box", "b_box"),
                     ("box", "b_cap")]
    datas = [mujoco.MjData(m) for m in (pairs, masks)]
    together = False
    for _ in range(300):
        for m, d in zip((pairs, masks), datas, strict=True):
            mujoco.mj_step(m, d)
        a, b = datas
        assert a.ncon == b.ncon
        for field in ("geom", "pos", "frame", "dist", "dim", "friction"):
            assert np.array_equal(getattr(a.contact, field), getattr(b.contact, field)), field
        kinds = {tuple(g) for g in a.contact.geom.tolist()}
        together |= {(1, 3), (2, 1)} <= kinds  # both geoms on the world's box at once
    assert np.array_equal(a.qpos, b.qpos)
    assert together
