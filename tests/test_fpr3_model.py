"""The spatial FPR's description (urdf/fpr3.urdf) and its planning model, with plain Pinocchio and MuJoCo.

Three quadrotors carry a platform (6 DOF) through three rigid legs: leg i is hinged to the platform at
r_i = Rz(a_i) [r_p 0 0], its frame R_li = Rz(a_i) Rx(-pi/2) Rz(q_i) (LS2N's convention), and a drone sits on
a ball joint at its tip s_i = p + R_p (r_i + R_li [l 0 0]). These tests read the committed URDF as it is,
without :mod:`fpr.robots`:

* the description: its geometry follows the convention above, its numbers follow ``urdf/parameters.yaml``
  (the leg's inertia given about the hinge, as LS2N's model does), and yourdfpy, Pinocchio and MuJoCo read it;
* MuJoCo (an independent URDF reader and rigid-body implementation) and Pinocchio agree on the mass matrix and
  the bias forces, the platform fixed and floating (with the map between their velocity coordinates);
* the planning model: the chain (platform, legs) with each drone a point mass at its leg's tip, in the
  coordinates q = [x y z psi theta phi q1 q2 q3] (the Z-Y-X, i.e. roll-pitch-yaw, angles of the platform, as
  the planar FPR's root joint); the thrust vectors F = J^-T (M q'' + c), J the tips' Jacobian; at a hover they
  balance the robot's weight; applied to the drones as free bodies joined to the tips by 3D point closures
  (pin.constraintDynamics), they give back the planned accelerations;
* the singular configurations of J found from the model, against a hand derivation.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
import yaml
import yourdfpy

from fpr.model import description

mujoco = pytest.importorskip("mujoco", reason="mujoco is in the test extra: pip install -e .[test]")

PARAMS = yaml.safe_load((description.URDF_DIR / "parameters.yaml").read_text(encoding="utf-8"))
TEXT = description.urdf_path("fpr3").read_text(encoding="utf-8")
G = PARAMS["gravity"]
LEGS = (1, 2, 3)
ANGLES = tuple(2 * np.pi * (i - 1) / 3 for i in LEGS)  # a_i
BALL = ("ball_pitch", "ball_yaw", "hinge")  # the ball joint's three hinges, in tree order
SEED = 2018


# ------------------------------------------------------------------------------------------ helpers


def _rz(a):
    return pin.rpy.rpyToMatrix(0.0, 0.0, a)


def _ry(a):
    return pin.rpy.rpyToMatrix(0.0, a, 0.0)


def _rx(a):
    return pin.rpy.rpyToMatrix(a, 0.0, 0.0)


def _euler_root() -> pin.JointModelComposite:
    """The platform's chart: x, y, z then yaw psi, pitch theta, roll phi (R = Rz Ry Rx, roll-pitch-yaw).

    The planar FPR's root joint (fpr.model.robot.euler_root_joint); its velocity is exactly the coordinates'
    rates, so that nq == nv and the thrust Jacobian is in the planning coordinates.
    """
    joint = pin.JointModelComposite()
    for j in (pin.JointModelPX(), pin.JointModelPY(), pin.JointModelPZ(),
              pin.JointModelRZ(), pin.JointModelRY(), pin.JointModelRX()):
        joint.addJoint(j)
    return joint


def _full_model(text: str = TEXT, root=None) -> pin.Model:
    """The whole tree (platform, legs, balls, drones) of a URDF text; root: None (fixed), or a root joint."""
    text = description.single_angle_urdf(text)
    model = pin.buildModelFromXML(text) if root is None else pin.buildModelFromXML(text, root)
    model.gravity.linear = np.array([0.0, 0.0, -G])
    return model


def _ball_joints(model: pin.Model) -> list[int]:
    return [model.getJointId(f"drone_{i}_{n}") for i in LEGS for n in BALL]


def _root_model(root) -> tuple[pin.Model, int]:
    """A model of the platform's root joint alone and the frame to hang the robot on.

    root: a Pinocchio joint model (e.g. :func:`_euler_root`, ``pin.JointModelFreeFlyer()``), or "chain": the
    chart's six joints one after the other (massless bodies between them), the same coordinates and
    dynamics as the composite joint, for Pinocchio's derivative algorithms: pin 4.1's computeRNEADerivatives,
    computeABADerivatives and Jacobian time variations are wrong on a composite joint with two or more
    rotations (finite differences disagree by O(1)), right on this chain.
    """
    model = pin.Model()
    parent = 0
    if isinstance(root, str):
        for name, joint in (("x", pin.JointModelPX()), ("y", pin.JointModelPY()), ("z", pin.JointModelPZ()),
                            ("psi", pin.JointModelRZ()), ("theta", pin.JointModelRY()),
                            ("phi", pin.JointModelRX())):
            parent = model.addJoint(parent, joint, pin.SE3.Identity(), name)
    else:
        parent = model.addJoint(parent, root, pin.SE3.Identity(), "root_joint")
    frame = pin.Frame("platform_root", parent, pin.SE3.Identity(), pin.FrameType.OP_FRAME)
    return model, model.addFrame(frame)


def _planning_model(text: str = TEXT, root=None, drones: str = "point") -> pin.Model:
    """The chain with the drones as point masses at the tips ("point") or without them ("none").

    From the URDF's own bodies: each drone's body becomes a point mass at its ball (or nothing), and the ball
    joints are locked, which puts the drone's mass (and the balls' rings) on the leg at its tip. Coordinates:
    the root's (:func:`_root_model`; default: the Z-Y-X chart), then q1, q2, q3.
    """
    tree = _full_model(text)  # the platform fixed: the root joint is added below
    for i in LEGS:
        j = tree.getJointId(f"drone_{i}_hinge")
        mass = tree.inertias[j].mass if drones == "point" else 0.0
        tree.inertias[j] = pin.Inertia(mass, np.zeros(3), np.zeros((3, 3)))
    tree = pin.buildReducedModel(tree, _ball_joints(tree), pin.neutral(tree))
    base, frame = _root_model(_euler_root() if root is None else root)
    model = pin.appendModel(base, tree, frame, pin.SE3.Identity())
    model.gravity.linear = np.array([0.0, 0.0, -G])
    return model


def _tip_jacobian(model: pin.Model, data: pin.Data, q) -> np.ndarray:
    """J: the tips' velocities (world axes) from the model's velocity, shape (9, nv) (LOCAL_WORLD_ALIGNED)."""
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    rows = [pin.getFrameJacobian(model, data, model.getFrameId(f"leg_{i}_tip"), pin.LOCAL_WORLD_ALIGNED)[:3]
            for i in LEGS]
    return np.vstack(rows)


def _tips(model: pin.Model, data: pin.Data, q) -> np.ndarray:
    pin.framesForwardKinematics(model, data, q)
    return np.array([data.oMf[model.getFrameId(f"leg_{i}_tip")].translation for i in LEGS])


def _ls2n_jacobian(pose, legs, model=None) -> np.ndarray:
    """LS2N's J: tips' velocities from [v_p (world), w_p (platform frame), q'], rows tip by tip.

    Pinocchio's free flyer has v_p in the platform frame: J_LS2N = J_ff diag(R_p^T, I, I).
    """
    model = model or _planning_model(root=pin.JointModelFreeFlyer())
    position, rotation = pose
    q = np.concatenate([position, pin.Quaternion(rotation).coeffs(), legs])
    jac = _tip_jacobian(model, model.createData(), q)
    jac[:, :3] = jac[:, :3] @ rotation.T
    return jac


def _rest_to_rest(tau):
    """The 9th-degree rest-to-rest blend and its derivatives 0..3 in tau (1st to 4th zero at both ends)."""
    c = np.array([0, 0, 0, 0, 0, 126, -420, 540, -315, 70], dtype=float)
    poly = np.polynomial.Polynomial(c)
    return [float(poly.deriv(k)(tau)) if k else float(poly(tau)) for k in range(4)]


def _motion(start, end, duration, t):
    """q, q', q'', q''' at time t of the rest-to-rest motion start -> end in ``duration`` seconds."""
    blend = _rest_to_rest(t / duration)
    delta = np.asarray(end) - np.asarray(start)
    return [np.asarray(start) + delta * blend[0]] + [delta * blend[k] / duration**k for k in (1, 2, 3)]


def _thrust_vectors(model, data, q, v, a) -> np.ndarray:
    """F = J^-T (M a + c) of the planning model, shape (3, 3) (one row per drone) [N]."""
    b = pin.rnea(model, data, q, v, a)
    return np.linalg.solve(_tip_jacobian(model, data, q).T, b).reshape(3, 3)


def _attitude(force, leg_direction) -> np.ndarray:
    """A drone attitude: its z axis along its thrust, its x axis in the plane of its leg and its thrust."""
    z = force / np.linalg.norm(force)
    y = np.cross(z, leg_direction)
    y /= np.linalg.norm(y)
    return np.column_stack([np.cross(y, z), y, z])


START = np.array([0.0, 0.0, PARAMS["leg_length"] * np.sin(np.pi / 4), 0.0, 0.0, 0.0] + [np.pi / 4] * 3)
"""LS2N's take-off pose: platform level at z = l sin 45 deg, legs 45 degrees below it, tips at z = 0."""
END = np.array([1.0, 0.2, 1.4, np.pi / 3, 0.1, np.deg2rad(20.0), 0.9, 0.6, 0.75])
"""Translated by about 1 m, yawed 60 degrees, tilted 20 degrees, the legs unequal (as the fpr3-tour)."""


# -------------------------------------------------------------------------------------- description


def test_readers_load_the_committed_urdf():
    """yourdfpy, Pinocchio and MuJoCo read urdf/fpr3.urdf as committed: the same joints, in the same order."""
    urdf = yourdfpy.URDF.load(str(description.urdf_path("fpr3")), load_meshes=False, build_scene_graph=True)
    assert urdf.validate() and urdf.base_link == "platform" and urdf.robot.name == "fpr3"
    joints = [f"q{i}" if n is None else f"drone_{i}_{n}" for i in LEGS for n in (None, *BALL)]
    assert sorted(urdf.actuated_joint_names) == sorted(joints)
    model = _full_model(root=_euler_root())
    assert (model.nq, model.nv) == (18, 18) and list(model.names)[2:] == joints
    mj = mujoco.MjModel.from_xml_path(str(description.urdf_path("fpr3")))
    assert [mj.joint(i).name for i in range(mj.njnt)] == joints
    assert not any(mj.jnt_limited)
    kinds = {joint.get("type") for joint in ET.fromstring(TEXT).iter("joint")}
    assert kinds == {"continuous", "fixed"}
    assert "Generated from urdf/fpr3.urdf.xacro" in TEXT


def test_masses_and_inertias_follow_the_parameters():
    """Every number from parameters.yaml; the leg's inertia, given about the hinge (LS2N), at its centre."""
    model = _full_model(root=pin.JointModelFreeFlyer())
    p = PARAMS
    expected = (p["platform_mass"] + 3 * (p["leg_mass"] + p["drone_mass"] + 2 * p["ball_ring_mass"]))
    assert pin.computeTotalMass(model) == pytest.approx(expected, rel=1e-14)
    platform = model.inertias[model.getJointId("root_joint")]
    assert platform.mass == p["platform_mass"]
    np.testing.assert_allclose(np.diag(platform.inertia),
                               [p["platform_ixx"], p["platform_iyy"], p["platform_izz"]])
    for i in LEGS:
        leg = model.inertias[model.getJointId(f"q{i}")]
        assert leg.mass == p["leg_mass"]
        np.testing.assert_allclose(leg.lever, [p["leg_com"], 0.0, 0.0])
        # about the hinge (the leg frame's origin): I_c + m (|c|^2 I - c c^T), LS2N's numbers
        c = leg.lever
        at_hinge = leg.inertia + leg.mass * (c @ c * np.eye(3) - np.outer(c, c))
        np.testing.assert_allclose(at_hinge, np.diag([p["leg_ixx"], p["leg_iyy"], p["leg_izz"]]), rtol=1e-12)
        drone = model.inertias[model.getJointId(f"drone_{i}_hinge")]
        assert drone.mass == p["drone_mass"]
        np.testing.assert_allclose(drone.lever, [0.0, 0.0, p["ball_offset"]])
        np.testing.assert_allclose(np.diag(drone.inertia), [p["drone_ixx"], p["drone_iyy"], p["drone_izz"]])
    assert np.all(np.linalg.eigvalsh(leg.inertia) > 0)


def test_geometry_follows_the_convention():
    """Tips at p + R_p (r_i + R_li [l 0 0]), hinge axes tangent to the r_p circle, q_i > 0 lowers the tip, and
    the drone's attitude Rz(a_i) Ry(q_i + pitch) Rz(yaw) Rx(hinge) in the platform frame (the ball's chart).
    """
    model = _full_model(root=pin.JointModelFreeFlyer())
    data = model.createData()
    length, radius = PARAMS["leg_length"], PARAMS["platform_radius"]
    rng = np.random.default_rng(SEED)
    for _ in range(5):
        q = pin.neutral(model)
        position, rotation = rng.normal(size=3), pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3))
        q[:3], q[3:7] = position, pin.Quaternion(rotation).coeffs()
        legs, ball = rng.uniform(-1.5, 1.5, 3), rng.uniform(-np.pi, np.pi, (3, 3))
        for i in LEGS:
            q[model.joints[model.getJointId(f"q{i}")].idx_q] = legs[i - 1]
            for k, name in enumerate(BALL):
                q[model.joints[model.getJointId(f"drone_{i}_{name}")].idx_q] = ball[i - 1, k]
        pin.framesForwardKinematics(model, data, q)
        for i, a in zip(LEGS, ANGLES, strict=True):
            frame = _rz(a) @ _rx(-np.pi / 2) @ _rz(legs[i - 1])
            tip = position + rotation @ (_rz(a) @ [radius, 0.0, 0.0] + frame @ [length, 0.0, 0.0])
            np.testing.assert_allclose(data.oMf[model.getFrameId(f"leg_{i}_tip")].translation, tip,
                                       atol=1e-12)
            hinge = data.oMi[model.getJointId(f"q{i}")]
            np.testing.assert_allclose(hinge.rotation[:, 2], rotation @ _rz(a) @ [0.0, 1.0, 0.0], atol=1e-12)
            attitude = _rz(a) @ _ry(legs[i - 1] + ball[i - 1, 0]) @ _rz(ball[i - 1, 1]) @ _rx(ball[i - 1, 2])
            centre = data.oMf[model.getFrameId(f"drone_{i}_center")]
            np.testing.assert_allclose(centre.rotation, rotation @ attitude, atol=1e-12)
            np.testing.assert_allclose(centre.translation, tip, atol=1e-12)  # ball_offset = 0: on the tip
    # q_i > 0 turns the tip towards the platform's -z; 45 degrees put the tips l sin 45 below the platform
    planning = _planning_model()
    tips = _tips(planning, planning.createData(), START)
    np.testing.assert_allclose(tips[:, 2], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.hypot(tips[:, 0], tips[:, 1]), radius + length * np.cos(np.pi / 4))


def test_xacro_arguments_change_the_robot():
    """A variant by xacro arguments (longer legs, the drone 0.1 m above its ball) changes what it should."""
    text = description.generate_urdf("fpr3", leg_length=1.2, ball_offset=0.1, platform_mass=0.5)
    model = _full_model(text, pin.JointModelFreeFlyer())
    tip = model.frames[model.getFrameId("leg_1_tip")].placement.translation
    np.testing.assert_allclose(tip, [1.2, 0.0, 0.0])
    np.testing.assert_allclose(model.inertias[model.getJointId("drone_2_hinge")].lever, [0.0, 0.0, 0.1])
    assert "drone_3_strut" in text and "drone_3_strut" not in TEXT
    assert pin.computeTotalMass(model) - pin.computeTotalMass(_full_model(root=pin.JointModelFreeFlyer())) \
        == pytest.approx(0.5 - PARAMS["platform_mass"], abs=1e-12)


# ------------------------------------------------------------------------------------------- MuJoCo


def _dense_mass_matrix(mj, data) -> np.ndarray:
    full = np.zeros((mj.nv, mj.nv))
    if hasattr(data, "qM"):  # MuJoCo 3: mj_fullM(m, dst, M)
        mujoco.mj_fullM(mj, full, data.qM)
    else:  # MuJoCo 4: mj_fullM(m, d, dst)
        mujoco.mj_fullM(mj, data, full)
    return full


def _mujoco(text: str, floating: bool):
    """MuJoCo's model of a URDF text; floating: with a free joint added on the platform (MjSpec)."""
    spec = mujoco.MjSpec.from_string(text)
    if floating:
        spec.body("platform").add_freejoint()
    mj = spec.compile()
    mj.opt.gravity[:] = (0.0, 0.0, -G)
    return mj


def _compare_with_mujoco(text: str, floating: bool, samples: int = 8, seed: int = SEED):
    """Largest differences (and scales) of M(q) and of the bias c(q, v) + g(q), MuJoCo vs Pinocchio.

    Floating: MuJoCo's free joint has [position, quaternion (w x y z)] and the velocity [v (world), w (body)];
    Pinocchio's [position, quaternion (x y z w)] and [v (body), w (body)]. With v_pin = S v_mj,
    S = diag(R^T, I, I): M_mj = S^T M_pin S and c_mj = S^T (c_pin + M_pin S' v_mj), with
    S' v_mj = (-w x v_body, 0).
    """
    mj = _mujoco(text, floating)
    data = mujoco.MjData(mj)
    model = _full_model(text, pin.JointModelFreeFlyer() if floating else None)
    pdata = model.createData()
    assert mj.nv == model.nv
    rng = np.random.default_rng(seed)
    worst_m = worst_b = scale_m = scale_b = 0.0
    for _ in range(samples):
        q, v = pin.neutral(model), rng.uniform(-3.0, 3.0, model.nv)
        angles = slice(7, None) if floating else slice(None)
        q[angles] = rng.uniform(-np.pi, np.pi, q[angles].size)
        s = np.eye(model.nv)
        if floating:
            rotation = pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3))
            quaternion = pin.Quaternion(rotation)
            q[:3], q[3:7] = rng.normal(size=3), quaternion.coeffs()
            data.qpos[:3], data.qpos[3:7], data.qpos[7:] = q[:3], [quaternion.w, *q[3:6]], q[7:]
            s[:3, :3] = rotation.T
        else:
            data.qpos[:] = q
        data.qvel[:] = v
        v_pin = s @ v
        s_dot_v = np.zeros(model.nv)
        if floating:
            s_dot_v[:3] = -np.cross(v_pin[3:6], v_pin[:3])
        mujoco.mj_forward(mj, data)
        m = pin.crba(model, pdata, q)
        m = np.triu(m) + np.triu(m, 1).T
        expected_m = s.T @ m @ s
        expected_b = s.T @ (pin.rnea(model, pdata, q, v_pin, np.zeros(model.nv)) + m @ s_dot_v)
        worst_m = max(worst_m, float(np.abs(_dense_mass_matrix(mj, data) - expected_m).max()))
        worst_b = max(worst_b, float(np.abs(data.qfrc_bias - expected_b).max()))
        scale_m, scale_b = max(scale_m, float(np.abs(m).max())), max(scale_b, float(np.abs(expected_b).max()))
    return worst_m, worst_b, scale_m, scale_b


@pytest.mark.parametrize("floating", [False, True], ids=["platform-fixed", "floating"])
def test_mujoco_and_pinocchio_agree_on_mass_matrix_and_bias(floating):
    """M(q) and c(q, v) + g(q) at random states: equal to 1e-9 in both simulators."""
    worst_m, worst_b, scale_m, scale_b = _compare_with_mujoco(TEXT, floating)
    assert scale_m > 1.0 and scale_b > 10.0  # the comparison is not between zeros
    assert worst_m < 1e-9 * scale_m, worst_m
    assert worst_b < 1e-9 * scale_b, worst_b


def test_mujoco_sees_a_variant():
    """Another description (drones off their balls, longer legs, heavier platform) still agrees: the check is
    not tuned to one file; and the floating map is needed (without S the bias differs).
    """
    text = description.generate_urdf("fpr3", ball_offset=0.1, leg_length=1.2, platform_mass=0.5)
    worst_m, worst_b, scale_m, scale_b = _compare_with_mujoco(text, floating=True, samples=4, seed=SEED + 1)
    assert worst_m < 1e-9 * scale_m and worst_b < 1e-9 * scale_b
    a, b = _mujoco(text, True), _mujoco(TEXT, True)
    heavier = float(np.sum(a.body_mass) - np.sum(b.body_mass))
    assert heavier == pytest.approx(0.5 - PARAMS["platform_mass"], abs=1e-12)


# ----------------------------------------------------------------------------------- planning model


def test_the_chart_is_the_free_flyer_and_singular_only_at_pitch_90_degrees():
    """The Z-Y-X chart's model is Pinocchio's free flyer seen through q' -> (v, w): same kinetic energy and
    tips; its Jacobian J = J_LS2N diag(I, E, I) with det E = -cos(theta): singular at theta = +-pi/2 only.
    """
    chart = _planning_model()
    flyer = _planning_model(root=pin.JointModelFreeFlyer())
    cdata, fdata = chart.createData(), flyer.createData()
    rng = np.random.default_rng(SEED)
    for theta in (*rng.uniform(-1.4, 1.4, 4), np.pi / 2):
        q = np.concatenate([rng.normal(size=3),
                            [rng.uniform(-np.pi, np.pi), theta, rng.uniform(-np.pi, np.pi)],
                            rng.uniform(0.2, 1.3, 3)])
        v = rng.normal(size=9)
        rotation = pin.rpy.rpyToMatrix(q[5], q[4], q[3])
        pin.forwardKinematics(chart, cdata, q, v)
        np.testing.assert_allclose(cdata.oMi[1].rotation, rotation, atol=1e-12)
        omega = cdata.v[1].angular  # the platform's angular velocity in its frame
        qf = np.concatenate([q[:3], pin.Quaternion(rotation).coeffs(), q[6:]])
        vf = np.concatenate([rotation.T @ v[:3], omega, v[6:]])
        assert pin.computeKineticEnergy(chart, cdata, q, v) == pytest.approx(
            pin.computeKineticEnergy(flyer, fdata, qf, vf), rel=1e-12)
        np.testing.assert_allclose(_tips(chart, cdata, q), _tips(flyer, fdata, qf), atol=1e-12)
        ls2n = _ls2n_jacobian((q[:3], rotation), q[6:], flyer)
        j = _tip_jacobian(chart, cdata, q)
        assert np.linalg.det(j) == pytest.approx(-np.cos(theta) * np.linalg.det(ls2n), abs=1e-12)
    assert np.linalg.matrix_rank(j) == 8  # the last pose: theta = pi/2, gimbal lock of the chart
    # the chart as six joints in a row (for Pinocchio's derivatives, see _root_model) is the same model
    chain = _planning_model(root="chain")
    hdata = chain.createData()
    q, v, a = rng.normal(size=9), rng.normal(size=9), rng.normal(size=9)
    np.testing.assert_allclose(pin.rnea(chain, hdata, q, v, a), pin.rnea(chart, cdata, q, v, a), atol=1e-12)
    np.testing.assert_allclose(_tip_jacobian(chain, hdata, q), _tip_jacobian(chart, cdata, q), atol=1e-12)


def test_hover_thrusts_balance_the_weight():
    """At rest, F = J^-T g(q): the thrusts along gravity sum to the robot's weight (the whole URDF's mass),
    and balance the weight's moment about the centre of mass too (the whole tree's, its balls at any angle).
    """
    model = _planning_model()
    data = model.createData()
    full = _full_model(root=_euler_root())
    fdata = full.createData()
    weight = pin.computeTotalMass(full) * G
    rng = np.random.default_rng(SEED)
    for _ in range(20):
        q = np.concatenate([rng.normal(size=3), rng.uniform(-0.5, 0.5, 3), rng.uniform(0.3, 1.3, 3)])
        force = _thrust_vectors(model, data, q, np.zeros(9), np.zeros(9))
        assert force[:, 2].sum() == pytest.approx(weight, abs=1e-9)
        np.testing.assert_allclose(force[:, :2].sum(axis=0), 0.0, atol=1e-9)
        q_full = np.concatenate([q[:7], rng.uniform(-np.pi, np.pi, 3), q[7:8], rng.uniform(-np.pi, np.pi, 3),
                                 q[8:9], rng.uniform(-np.pi, np.pi, 3)])
        centre = pin.centerOfMass(full, fdata, q_full)
        moment = sum(np.cross(s - centre, f) for s, f in zip(_tips(model, data, q), force, strict=True))
        np.testing.assert_allclose(moment, 0.0, atol=1e-9)
        assert np.all(force[:, 2] > 0)  # these poses hover with every drone pulling up


def _constrained_model(text: str = TEXT):
    """The plant's formulation: the chain a tree (drones removed), each drone a free body (its own inertia,
    its frame at its ball) joined to its leg's tip by a 3D point closure.
    """
    model = _planning_model(text, drones="none")
    full = _full_model(text, pin.JointModelFreeFlyer())
    constraints = pin.StdVec_RigidConstraintModel()
    flyers = []
    for i in LEGS:
        flyer = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), f"drone_{i}_freeflyer")
        model.appendBodyToJoint(flyer, full.inertias[full.getJointId(f"drone_{i}_hinge")], pin.SE3.Identity())
        tip = model.frames[model.getFrameId(f"leg_{i}_tip")]
        constraints.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, tip.parentJoint,
                                                    tip.placement, flyer, pin.SE3.Identity(), pin.LOCAL))
        flyers.append(flyer)
    data = model.createData()
    datas = pin.StdVec_RigidConstraintData()
    for constraint in constraints:
        datas.append(constraint.createData())
    pin.initConstraintDynamics(model, data, constraints, datas)
    return model, data, constraints, datas, flyers


def _replay(text: str, times, rng) -> float:
    """Largest difference between the planned accelerations of the motion START -> END and those of the
    constrained model under the planned thrusts (each drone turned along its thrust, spinning at random).
    """
    planning = _planning_model(text)
    pdata = planning.createData()
    model, data, constraints, datas, flyers = _constrained_model(text)
    settings = pin.ProximalSettings(1e-14, 1e-12, 100)
    worst = 0.0
    for t in times:
        q, v, a, _ = _motion(START, END, 3.0, t)
        force = _thrust_vectors(planning, pdata, q, v, a)
        jac = _tip_jacobian(planning, pdata, q)
        tips = [pdata.oMf[planning.getFrameId(f"leg_{i}_tip")] for i in LEGS]
        qc, vc = np.zeros(model.nq), np.zeros(model.nv)
        qc[:9], vc[:9] = q, v
        for k, (flyer, tip) in enumerate(zip(flyers, tips, strict=True)):
            attitude = _attitude(force[k], tip.rotation[:, 0])
            iq, iv = model.joints[flyer].idx_q, model.joints[flyer].idx_v
            qc[iq:iq + 7] = np.concatenate([tip.translation, pin.Quaternion(attitude).coeffs()])
            vc[iv:iv + 6] = np.concatenate([attitude.T @ (jac[3 * k:3 * k + 3] @ v), rng.normal(size=3)])
        tau = np.zeros(model.nv)
        pin.computeJointJacobians(model, data, qc)
        for k, flyer in enumerate(flyers):  # the thrust, a world force at the drone's centre of mass
            frame = pin.getJointJacobian(model, data, flyer, pin.LOCAL_WORLD_ALIGNED)
            centre = pin.SE3(np.eye(3), data.oMi[flyer].rotation @ model.inertias[flyer].lever)
            tau += frame.T @ centre.toActionMatrix().T @ np.concatenate([force[k], np.zeros(3)])
        ddq = pin.constraintDynamics(model, data, qc, vc, tau, constraints, datas, settings)
        worst = max(worst, float(np.abs(ddq[:9] - a).max()))
    return worst


def test_planned_accelerations_come_back_from_the_constrained_model():
    """The thrusts F = J^-T (M q'' + c) of a motion (the take-off pose -> translated, yawed 60 degrees,
    tilted 20), applied to the drones as free bodies on 3D point closures, give back q'' to 1e-6
    (pin.constraintDynamics); the drones' attitudes and spins do not matter when they sit on the tips at their
    centres of mass.
    """
    rng = np.random.default_rng(SEED)
    worst = _replay(TEXT, np.linspace(0.0, 3.0, 9), rng)
    assert worst < 1e-6, worst
    # a drone 0.1 m above its ball is a pendulum the point-mass planning model leaves out: then it differs
    assert _replay(description.generate_urdf("fpr3", ball_offset=0.1), (0.7, 1.5), rng) > 1e-3


def test_thrust_rate_from_pinocchio_derivatives():
    """F' along a motion from Pinocchio alone: J^T F = b gives F' = J^-T (b' - J'^T F), b' = dtau/dq q' +
    dtau/dv q'' + M q''' (computeRNEADerivatives), J' (frame Jacobian time variation); against central
    differences of F along the motion.
    """
    model = _planning_model(root="chain")  # not the composite joint: see _root_model
    data = model.createData()
    step = 1e-5
    for t in (0.4, 1.1, 2.2):
        q, v, a, jerk = _motion(START, END, 3.0, t)
        force = _thrust_vectors(model, data, q, v, a).reshape(-1)
        dtau_dq, dtau_dv, mass = pin.computeRNEADerivatives(model, data, q, v, a)
        mass = np.triu(mass) + np.triu(mass, 1).T
        b_rate = dtau_dq @ v + dtau_dv @ a + mass @ jerk
        pin.computeJointJacobiansTimeVariation(model, data, q, v)
        pin.updateFramePlacements(model, data)
        j_rate = np.vstack([pin.getFrameJacobianTimeVariation(model, data, model.getFrameId(f"leg_{i}_tip"),
                                                              pin.LOCAL_WORLD_ALIGNED)[:3] for i in LEGS])
        rate = np.linalg.solve(_tip_jacobian(model, data, q).T, b_rate - j_rate.T @ force)
        ahead = _thrust_vectors(model, data, *_motion(START, END, 3.0, t + step)[:3]).reshape(-1)
        behind = _thrust_vectors(model, data, *_motion(START, END, 3.0, t - step)[:3]).reshape(-1)
        np.testing.assert_allclose(rate, (ahead - behind) / (2 * step), atol=1e-5 * (1 + np.abs(rate).max()))
        assert np.abs(rate).max() > 0.1  # the thrusts do change


# ------------------------------------------------------------------------------------ singularities


def _symmetric_determinant(q):
    """The determinant of J_LS2N with the three legs at q, by hand: -(27/4) l^3 sin^3 q (r_p + l cos q)^3."""
    length, radius = PARAMS["leg_length"], PARAMS["platform_radius"]
    return -27 / 4 * length**3 * np.sin(q) ** 3 * (radius + length * np.cos(q)) ** 3


def test_determinant_of_the_tips_jacobian():
    """The determinant of J (velocity [v_p world, w_p platform, q'] as LS2N, rows tip by tip), by hand.

    Rows of leg i, turned by Rz(-a_i), then by (y_i, hinge axis, leg direction): the column of q_i is l y_i
    (y_i = dR_li/dq_i [1 0 0]), so det J = +-l^3 det P with P the 6 x 6 Pluecker coordinates (f, s_i x f) of
    the lines through each tip along its hinge's axis and along its leg. With the legs at one angle q, the leg
    lines meet at C on the platform's axis; about C, det P = det[legs] det[moments of the axis lines]
    = (-(3 sqrt 3 / 2) sin q cos^2 q) ((3 sqrt 3 / 2) h^2 rho), rho = r_p + l cos q the tips' radius and
    h = rho tan q: det J = -(27/4) l^3 sin^3 q rho^3. DESIGN.md's -1.69 at 45 degrees is this; it does not
    depend on the platform's pose.
    """
    rng = np.random.default_rng(SEED)
    flyer = _planning_model(root=pin.JointModelFreeFlyer())
    for q in (0.1, 0.5, np.pi / 4, 1.2, 1.6, 2.0, -0.7):
        pose = (rng.normal(size=3), pin.rpy.rpyToMatrix(*rng.uniform(-np.pi, np.pi, 3)))
        det = np.linalg.det(_ls2n_jacobian(pose, [q] * 3, flyer))
        assert det == pytest.approx(_symmetric_determinant(q), rel=1e-10, abs=1e-14)
    det = np.linalg.det(_ls2n_jacobian((np.zeros(3), np.eye(3)), [np.pi / 4] * 3, flyer))
    assert round(det, 2) == -1.69


def test_singular_configurations():
    """Found from the model: J loses rank with all legs in the platform's plane (by 3), with two of them
    there, and where the tips meet on the platform's axis (cos q = -r_p / l); one leg in the plane is not
    singular.
    """
    flyer = _planning_model(root=pin.JointModelFreeFlyer())
    pose = (np.zeros(3), np.eye(3))
    length, radius = PARAMS["leg_length"], PARAMS["platform_radius"]

    def singular_values(legs):
        return np.linalg.svd(_ls2n_jacobian(pose, legs, flyer), compute_uv=False)

    flat = singular_values([0.0, 0.0, 0.0])
    assert np.sum(flat < 1e-12 * flat[0]) == 3
    assert singular_values([0.0, 0.0, 0.7])[-1] < 1e-12
    assert singular_values([np.arccos(-radius / length)] * 3)[-1] < 1e-12
    assert singular_values([0.0, 0.7, 0.7])[-1] > 0.05
    # along the legs' common angle the smallest singular value rises from 0 at the plane and falls to 0 again
    line = np.linspace(0.0, np.arccos(-radius / length), 41)
    smallest = np.array([singular_values([q] * 3)[-1] for q in line])
    assert smallest[0] < 1e-12 and smallest[-1] < 1e-12 and np.all(smallest[1:-1] > 1e-4)
    assert 0.5 < line[np.argmax(smallest)] < 1.2


def test_no_vertical_force_with_the_legs_in_the_platforms_plane():
    """With q = 0 every tip force that does not turn its leg lies in the platform's plane: the drones cannot
    hold the platform up. Lifting the platform with the tips fixed (v_z = 1, q_i' = 1/l) is a motion J
    leaves out, and gravity does work along it, (m_p + 3 m_leg (1 - c/l)) g: no thrusts solve J^T F = g(q)
    (a hover).
    """
    model = _planning_model()
    data = model.createData()
    q = np.concatenate([[0.0, 0.0, 1.0, 0.3, 0.0, 0.0], [0.0] * 3])
    length, p = PARAMS["leg_length"], PARAMS
    lift = np.concatenate([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [1.0 / length] * 3])
    jac = _tip_jacobian(model, data, q)
    np.testing.assert_allclose(jac @ lift, 0.0, atol=1e-12)
    gravity = pin.computeGeneralizedGravity(model, data, q)
    work = (p["platform_mass"] + 3 * p["leg_mass"] * (1 - p["leg_com"] / length)) * G
    assert lift @ gravity == pytest.approx(work, rel=1e-12)
    force = np.linalg.lstsq(jac.T, gravity, rcond=None)[0]
    residual = np.linalg.norm(jac.T @ force - gravity)
    assert residual >= work / np.linalg.norm(lift) * (1 - 1e-9)
    # away from the plane the same hover is solvable
    q[6:] = 0.3
    jac = _tip_jacobian(model, data, q)
    gravity = pin.computeGeneralizedGravity(model, data, q)
    np.testing.assert_allclose(jac.T @ np.linalg.solve(jac.T, gravity), gravity, atol=1e-9)
