"""The spatial FPR's kind (fpr.robots.fpr3) through ``fpr.load("fpr3")``: its geometry against Pinocchio and a hand
derivation, its motion inputs against Pinocchio's inverse dynamics, the full model's and the constrained model's
forward dynamics (the round trips), and their derivatives (complex step, dual numbers, finite differences).
"""

import math

import numpy as np
import pinocchio as pin
import pytest
from test_fpr3_model import _constrained_model

import fpr
from fpr.model.dual import Dual
from fpr.model.jets import Jet
from fpr.robots.fpr3 import LEG_ANGLES, ball_angles
from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask
from planners.missions.mission import load_mission
from planners.optimisation.solving import Grid

SEED = 2018


@pytest.fixture(scope="module")
def robot():
    return fpr.load("fpr3")


def _rotation(s):
    """R_p = Rz(psi) Ry(theta) Rx(phi) of a planning pose."""
    return pin.rpy.rpyToMatrix(s[5], s[4], s[3])


def _poses(rng, n):
    """Random planning poses inside the workspace's box (tilts to 0.4 rad, legs 0.4..1.2 rad)."""
    return np.concatenate([rng.normal(size=(n, 3)) + [0.0, 0.0, 1.5], rng.uniform(-0.4, 0.4, (n, 3)),
                           rng.uniform(0.4, 1.2, (n, 3))], axis=1)


def _motions(rng, n, scale=0.6):
    """Random motion jets (5, n, 9) about random poses."""
    motion = scale * rng.normal(size=(5, n, 9))
    motion[0] = _poses(rng, n)
    return motion


# ------------------------------------------------------------------------------------------ geometry


def test_ball_angles_follow_the_attitude_rule():
    """The drone R = P_i Ry(q_i + pitch) Rz(yaw) Rx(roll) of ball_angles has its z along F_i and its x normal to
    leg i's hinge axis t_i = R_p Rz(a_i) e_y, yaw 0.
    """
    rng = np.random.default_rng(SEED)
    for _ in range(20):
        s = _poses(rng, 1)[0]
        force = rng.normal(size=(3, 3)) + [0.0, 0.0, 6.0]
        angles = ball_angles(_rotation(s), s[6:9], force)
        for i, (pitch, yaw, roll) in enumerate(angles):
            radial = _rotation(s) @ pin.rpy.rpyToMatrix(0.0, 0.0, LEG_ANGLES[i])
            drone = radial @ pin.rpy.rpyToMatrix(0.0, s[6 + i] + pitch, 0.0) @ pin.rpy.rpyToMatrix(0.0, 0.0, yaw) \
                @ pin.rpy.rpyToMatrix(roll, 0.0, 0.0)
            np.testing.assert_allclose(drone[:, 2], force[i] / np.linalg.norm(force[i]), atol=1e-14)
            assert abs(drone[:, 0] @ radial[:, 1]) < 1e-14
            assert yaw == 0.0 and abs(s[6 + i] + pitch) < np.pi


def test_tips_and_jacobian_are_pinocchios(robot):
    kind = robot.kind
    model = kind.point_model
    data = model.createData()
    rng = np.random.default_rng(SEED)
    for s in _poses(rng, 8):
        pin.computeJointJacobians(model, data, s)
        pin.updateFramePlacements(model, data)
        ids = [model.getFrameId(f"leg_{i}_tip") for i in (1, 2, 3)]
        tips = np.array([data.oMf[f].translation for f in ids])
        jac = np.vstack([pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED)[:3] for f in ids])
        np.testing.assert_allclose(kind.drone_joints(s), tips, atol=1e-13)
        np.testing.assert_allclose(kind.chain_jacobian(s), jac, atol=1e-12)


def test_singular_lines_determinant(robot):
    """det J_chart = cos(theta) l^3 det K (K the legs' six lines), det K = (27/4) sin^3 q (r_p + l cos q)^3 for three
    legs at one angle (DESIGN's hand formula); zero with two legs in the platform's plane, not with one.
    """
    kind = robot.kind
    length, r_p = kind.geometry.lengths[0], kind.geometry.radius[0]
    rng = np.random.default_rng(SEED)
    for s in _poses(rng, 8):
        det_j = np.linalg.det(kind.chain_jacobian(s))
        assert det_j == pytest.approx(np.cos(s[4]) * length**3 * kind.geometry.line_determinant(s[6:9]), rel=1e-10)
    for q in (0.2, 0.7, 1.3):
        hand = 27 / 4 * np.sin(q) ** 3 * (r_p + length * np.cos(q)) ** 3
        assert kind.geometry.line_determinant(np.full(3, q)) == pytest.approx(hand, rel=1e-12)
    assert abs(kind.geometry.line_determinant(np.array([0.0, 0.0, 0.8]))) < 1e-14
    assert abs(kind.geometry.line_determinant(np.array([0.0, 0.8, 0.8]))) > 1e-2
    edge = np.array(kind.reference_chain)
    edge[6:9] = robot.margins.angle
    assert kind.workspace_margins(edge)["singular"] == pytest.approx(0.0, abs=1e-14)
    assert kind.workspace_margins(np.array(kind.reference_chain))["singular"] > 0.5


def test_reference_pose_is_inside_the_workspace(robot):
    margins = robot.kind.workspace_margins(np.array(robot.kind.reference_chain))
    assert min(float(v) for v in margins.values()) > 0
    robot.kind.check_pose(np.array(robot.kind.reference_chain), None, "reference")


# ------------------------------------------------------------------------------------------ motion inputs


def test_hover_thrusts_sum_to_the_weight(robot):
    """At rest the thrusts along gravity sum to the robot's weight and their horizontal parts to 0 (1e-9 N)."""
    rng = np.random.default_rng(SEED)
    motion = np.zeros((5, 20, 9))
    motion[0] = _poses(rng, 20)
    inputs = robot.kind.motion_inputs(motion)
    weight = robot.total_mass * robot.parameters["gravity"]
    np.testing.assert_allclose(inputs.thrust_vector[..., 2].sum(axis=1), weight, atol=1e-9, rtol=0)
    np.testing.assert_allclose(inputs.thrust_vector[..., :2].sum(axis=1), 0.0, atol=1e-9)
    np.testing.assert_allclose(inputs.attitude_rate_squared, 0.0, atol=1e-20)


def test_thrust_vectors_are_pinocchios_inverse_dynamics(robot):
    """F = J^-T (M s'' + c) by pin.rnea and the frames' Jacobian, against the spatial jets' F."""
    kind = robot.kind
    model = kind.point_model
    data = model.createData()
    motion = _motions(np.random.default_rng(SEED), 10)
    inputs = kind.motion_inputs(motion)
    for k in range(motion.shape[1]):
        b = pin.rnea(model, data, motion[0, k], motion[1, k], motion[2, k])
        force = np.linalg.solve(kind.chain_jacobian(motion[0, k]).T, b).reshape(3, 3)
        np.testing.assert_allclose(inputs.thrust_vector[k], force, atol=1e-11)
        np.testing.assert_allclose(inputs.joint_velocity[k].reshape(-1), kind.chain_jacobian(motion[0, k])
                                   @ motion[1, k], atol=1e-12)


def test_full_model_gives_back_the_planned_accelerations(robot):
    """The full 18-coordinate model (drones rigid on their balls) under the planned thrusts and torques gives back
    the planned accelerations of the chain and of the ball angles (forward dynamics, 1e-6).
    """
    motion = _motions(np.random.default_rng(SEED), 12)
    inputs = robot.kind.motion_inputs(motion)
    q, v, a = inputs.full_state(robot)
    for k in range(q.shape[0]):
        got = robot.forward_dynamics(q[k], v[k], inputs.thrust[k], inputs.torque[k])
        np.testing.assert_allclose(got, a[k], atol=1e-6)
    # the attitude rule: the ball angles of the thrust vectors, yaw 0
    for k in range(q.shape[0]):
        np.testing.assert_allclose(inputs.attitude[k], ball_angles(_rotation(motion[0, k]), motion[0, k, 6:9],
                                                                   inputs.thrust_vector[k]), atol=1e-14)


def test_constrained_model_gives_back_the_planned_accelerations(robot):
    """The plant's formulation (drones free bodies on 3D point closures at the tips, pin.constraintDynamics) under
    the planned thrusts, the drones turned and spinning as planned, gives back the chain's planned accelerations
    (1e-6).
    """
    motion = _motions(np.random.default_rng(SEED + 1), 6)
    inputs = robot.kind.motion_inputs(motion)
    q_full, v_full, _ = inputs.full_state(robot)
    model, data, constraints, datas, flyers = _constrained_model()
    settings = pin.ProximalSettings(1e-14, 1e-12, 100)
    full, fdata = robot.model, robot.data
    for k in range(motion.shape[1]):
        qp, vp = robot.to_pinocchio(q_full[k]), robot.to_pinocchio(v_full[k])
        pin.forwardKinematics(full, fdata, qp, vp)
        qc, vc = np.zeros(model.nq), np.zeros(model.nv)
        qc[:9], vc[:9] = motion[0, k], motion[1, k]
        for i, flyer in enumerate(flyers):
            joint = robot.hinge_joint_ids[i]
            placement, velocity = fdata.oMi[joint], fdata.v[joint]
            iq, iv = model.joints[flyer].idx_q, model.joints[flyer].idx_v
            qc[iq:iq + 7] = pin.SE3ToXYZQUAT(placement)
            vc[iv:iv + 6] = velocity.vector
        tau = np.zeros(model.nv)
        pin.computeJointJacobians(model, data, qc)
        for i, flyer in enumerate(flyers):
            jac = pin.getJointJacobian(model, data, flyer, pin.LOCAL)
            wrench = np.concatenate([[0.0, 0.0, inputs.thrust[k, i]], inputs.torque[k, i]])
            tau += jac.T @ wrench
        ddq = pin.constraintDynamics(model, data, qc, vc, tau, constraints, datas, settings)
        np.testing.assert_allclose(ddq[:9], motion[2, k], atol=1e-6)


def test_offset_drone_torques_and_thrust():
    """With the drones' centres 0.1 m above their balls, the torques hold the ball rows of the full model exactly
    and the thrust makes the chain's residual force normal to each drone's thrust axis (the pendulum the
    point-drone plan leaves out is lateral).
    """
    robot = fpr.load("fpr3", ball_offset=0.1)
    kind = robot.kind
    motion = _motions(np.random.default_rng(SEED), 6)
    inputs = kind.motion_inputs(motion)
    q, v, a = inputs.full_state(robot)
    balls = robot.indices(robot.layout.attitude)
    for k in range(q.shape[0]):
        qp, vp, ap = robot.to_pinocchio(q[k]), robot.to_pinocchio(v[k]), robot.to_pinocchio(a[k])
        needed = robot.T.T @ pin.rnea(robot.model, robot.data, qp, vp, ap)
        residual = needed - robot.generalized_input(q[k], inputs.thrust[k], inputs.torque[k])
        scale = np.abs(needed).max()
        np.testing.assert_allclose(residual[balls], 0.0, atol=1e-10 * scale)
        lateral = np.linalg.solve(kind.chain_jacobian(motion[0, k]).T, residual[:9]).reshape(3, 3)
        axes = inputs.thrust_vector[k] / np.linalg.norm(inputs.thrust_vector[k], axis=1, keepdims=True)
        np.testing.assert_allclose(np.sum(lateral * axes, axis=1), 0.0, atol=1e-10 * scale)
        assert np.abs(lateral).max() > 1e-3  # the pendulum's lateral force is there


def test_offset_drones_perturb_the_chain_to_first_order():
    """The full model's forward dynamics under the planned inputs leaves the plan by a residual first order in the
    drones' offset d (the pendulum the point-drone plan leaves out), 0 at d = 0.
    """
    motion = _motions(np.random.default_rng(SEED), 5, scale=0.3)
    residuals = []
    for d in (0.0, 0.01, 0.02):
        robot = fpr.load("fpr3", ball_offset=d)
        inputs = robot.kind.motion_inputs(motion)
        q, v, a = inputs.full_state(robot)
        residuals.append(max(np.abs(robot.forward_dynamics(q[k], v[k], inputs.thrust[k], inputs.torque[k])
                                    - a[k]).max() for k in range(q.shape[0])))
    assert residuals[0] < 1e-6 < 1e-3 < residuals[1]  # (at 0.1 m the second order shows: 0.09 against 0.03 at 0.05)
    assert residuals[2] / residuals[1] == pytest.approx(2.0, rel=0.25)


# ------------------------------------------------------------------------------------------ derivatives


_FIELDS = ("thrust_vector", "thrust", "attitude", "attitude_rate", "attitude_rate_squared", "angular_velocity",
           "torque", "rotor_speed_squared", "joint_velocity")


def test_motion_inputs_derivatives_complex_dual_and_finite_differences(robot):
    """d(motion inputs)/d(motion) by complex step, dual numbers and central differences agree."""
    kind = robot.kind
    rng = np.random.default_rng(SEED)
    motion = _motions(rng, 3)
    directions = [(r, j) for r in range(5) for j in range(9)]
    seeded = Dual.seeded(motion, [(r, slice(None), j) for r, j in directions])
    dual = kind.motion_inputs(seeded)
    for d in rng.choice(len(directions), 12, replace=False):
        r, j = directions[d]
        step = np.zeros_like(motion)
        step[r, :, j] = 1.0
        complex_out = kind.motion_inputs(motion + 1e-30j * step)
        h = 1e-6
        plus, minus = kind.motion_inputs(motion + h * step), kind.motion_inputs(motion - h * step)
        for name in _FIELDS:
            by_complex = np.imag(getattr(complex_out, name)) / 1e-30
            by_dual = getattr(dual, name).full_tangents(len(directions))[d]
            by_difference = (getattr(plus, name) - getattr(minus, name)) / (2 * h)
            # each quantity's derivative, and its value (the complex step's round-off follows the value's size)
            scale = max(1.0, np.abs(by_complex).max(), 1e-4 * np.abs(getattr(plus, name)).max())
            np.testing.assert_allclose(by_dual, by_complex, atol=1e-11 * scale, err_msg=name)
            np.testing.assert_allclose(by_difference, by_complex, atol=1e-5 * scale, err_msg=name)


def test_rates_are_the_time_derivatives_of_the_attitudes(robot):
    """The attitude rates and accelerations, the thrust vectors' rates and |w| against the motion sampled along
    its own Taylor expansion in time (central differences in t).
    """
    kind = robot.kind
    motion = _motions(np.random.default_rng(SEED), 4)
    h = 1e-5

    def shifted(t):
        jet = Jet(np.concatenate([motion, np.zeros((2,) + motion.shape[1:])]))  # derivatives 5, 6 = 0
        return np.stack([sum(jet.d[k + m] * t**m / math.factorial(m) for m in range(5 - k)) for k in range(5)])

    now, plus, minus = (kind.motion_inputs(shifted(t)) for t in (0.0, h, -h))
    np.testing.assert_allclose((plus.attitude - minus.attitude) / (2 * h), now.attitude_rate, atol=1e-6)
    np.testing.assert_allclose((plus.attitude_rate - minus.attitude_rate) / (2 * h), now.attitude_acceleration,
                               atol=1e-5)
    np.testing.assert_allclose((plus.thrust_vector - minus.thrust_vector) / (2 * h), now.thrust_vector_rate,
                               atol=1e-5)
    np.testing.assert_allclose(np.sum(now.angular_velocity**2, axis=-1), now.attitude_rate_squared, rtol=1e-12)


def test_one_step_nlp_dual_equals_complex_step():
    """The planner's node sensitivities of the fpr3 tour by dual numbers and by complex step."""
    mission = load_mission("fpr3-tour")
    problem = one_step_problem(WayPointTask.of(mission, mission.load_robot()), Grid())
    x = problem.x_of(problem.points)
    x = x + 0.01 * np.random.default_rng(1).standard_normal(x.size)
    points = problem.points_of(x)
    out = {}
    for way in ("complex", "dual"):
        problem.derivatives = way
        out[way] = problem._node_derivatives(points, problem.motion(points))
    del problem.derivatives
    for ref, got in zip(out["complex"], out["dual"], strict=True):
        scale = np.abs(ref).max()
        np.testing.assert_allclose(got, ref, atol=1e-11 * scale, rtol=0)


def test_attitude_margins_scaled_and_unscaled_agree(robot):
    """The tilt rows: unscaled the angle to the bound, scaled the cosine's margin (same sign); the ball-roll rows
    the roll's margins; a drone thrusting along its leg's hinge axis breaks them.
    """
    motion = _motions(np.random.default_rng(SEED), 6)
    inputs = robot.kind.motion_inputs(motion)
    bound = np.pi / 2 - robot.margins.angle
    scaled, natural = robot.kind.attitude_margins(inputs, True), robot.kind.attitude_margins(inputs, False)
    for i in range(3):
        force = inputs.thrust_vector[:, i]
        tilt = np.arccos(force[:, 2] / np.linalg.norm(force, axis=1))
        assert [name for name, _, _ in natural[i]] == [f"tilt_{i + 1}"] + [f"ball_roll_{i + 1}"] * 2
        np.testing.assert_allclose(natural[i][0][2], bound - tilt, atol=1e-12)
        np.testing.assert_allclose(scaled[i][0][2], np.cos(tilt) - np.cos(bound), atol=1e-12)
        np.testing.assert_allclose(natural[i][2][2], bound - inputs.attitude[:, i, 2], atol=1e-15)
    hinge_axis = _rotation(motion[0, 0]) @ pin.rpy.rpyToMatrix(0.0, 0.0, LEG_ANGLES[0])[:, 1]
    sideways = ball_angles(_rotation(motion[0, 0]), motion[0, 0, 6:9], np.array([hinge_axis, [0, 0, 1], [0, 0, 1]]))
    assert abs(sideways[0, 2]) == pytest.approx(np.pi / 2) and abs(sideways[0, 2]) > bound


def test_a_gust_acts_through_the_virtual_work_of_its_point(robot):
    """A known gust's generalised force on the chain (planners.problem.disturbance.generalized_gust) is the force's
    virtual work through its point's displacement (world x, y, z), by central differences of the point's position:
    on the platform's centre and on a drone's tip.
    """
    from planners.missions.events import GustEvent
    from planners.problem.disturbance import generalized_gust

    rng = np.random.default_rng(7)
    s = np.array(robot.kind.reference_chain) + rng.uniform(-0.1, 0.1, 9)
    force = (0.0, 2.0, -3.0)  # a gust's force is drawn in the world's y-z plane
    h = 1e-6
    for body, point in (("end_effector", lambda x: robot.kind.task_points(x)[0]),
                        ("drone_2", lambda x: robot.kind.drone_joints(x)[1])):
        gust = GustEvent(0.0, force, 1.0, body, 0.0)
        q = generalized_gust(robot, (gust,), [0.5], s[None], rise=0.0)[0, 0]
        expected = [np.dot(force, (point(s + h * e) - point(s - h * e)) / (2 * h)) for e in np.eye(9)]
        np.testing.assert_allclose(q, expected, atol=1e-7)


@pytest.mark.parametrize("key, value", [("leg_length", 0.0), ("platform_mass", -1.0), ("ball_offset", 5.0)])
def test_a_spatial_parameter_out_of_its_physical_range_is_refused_by_name(key, value):
    from fpr.model.errors import ModelArgumentError

    with pytest.raises(ModelArgumentError, match=key):
        fpr.load("fpr3", **{key: value})


@pytest.mark.parametrize("overrides, field", [({"leg_iyy": 1e-4}, "leg_iyy"), ({"leg_izz": 0.02}, "leg_izz"),
                                              ({"leg_com": 0.8}, "leg_com"), ({"leg_mass": 0.2}, "leg_mass")])
def test_a_leg_lighter_about_its_hinge_than_its_centre_of_mass_allows_is_refused_by_name(overrides, field):
    """The leg's inertia is given about the hinge; about the centre of mass it is that less m c^2, which must stay
    positive (0.035 - 0.066 0.599^2 = 0.0113 kg m^2 by default): one clear error naming the field, not the xacro's.
    """
    from fpr.model.errors import ModelArgumentError

    with pytest.raises(ModelArgumentError, match=f"{field} = .*must exceed leg_mass leg_com\\^2") as error:
        fpr.load("fpr3", **overrides)
    assert error.value.argument == field
    fpr.load("fpr3", leg_iyy=0.03, leg_izz=0.03)  # about the hinge 0.03 > 0.0237: a lighter leg, still physical


def test_a_mission_with_an_unphysical_leg_inertia_exits_2_naming_the_field(tmp_path):
    import subprocess
    import sys

    from planners.missions.mission import load_mission

    text = load_mission("fpr3-tour").to_toml()
    assert text.count("[robot_parameters]") == 1
    (tmp_path / "m.toml").write_text(text.replace("[robot_parameters]", "[robot_parameters]\nleg_iyy = 1e-4", 1))
    run = subprocess.run([sys.executable, "-m", "fpr.plan", "--mission", str(tmp_path / "m.toml"), "--method", "none",
                          "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1 and "robot_parameters.leg_iyy" in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("overrides, field", [({"leg_iyy": 0.1}, "leg_iyy"), ({"leg_ixx": 0.03}, "leg_ixx"),
                                              ({"platform_izz": 0.01}, "platform_izz")])
def test_a_leg_or_platform_inertia_no_rigid_body_has_is_refused_by_name(overrides, field):
    """The triangle inequalities of the principal inertias, the legs' taken about their centres of mass (where the
    URDF holds them).
    """
    from fpr.model.errors import ModelArgumentError

    with pytest.raises(ModelArgumentError, match=f"{field} = .*more than the sum of the two other") as error:
        fpr.load("fpr3", **overrides)
    assert error.value.argument == field
