"""The spatial FPR's plant and controller hooks (fpr/robots/fpr3_control.py): the closed chain against the minimal
model, the reader, the drones' attitude targets, and the closed loop at hover and along a smooth motion.
"""

import numpy as np
import pinocchio as pin
import pytest

import fpr.robots
from controllers.ctc import CascadedController, Reference
from fpr import _native as native
from fpr.model.constrained import build_closed_chain
from fpr.robots.fpr3 import Fpr3
from fpr.robots.fpr3_control import ball_angles_of
from fpr.sim.plant import Plant

SEED = 23
FPS = 30.0


@pytest.fixture(scope="module")
def robot():
    """The spatial FPR, registered for the module when the registry does not know it yet."""
    added = "fpr3" not in fpr.robots.names()
    if added:
        fpr.robots.register(Fpr3)
    try:
        yield fpr.robots.load("fpr3")
    finally:
        if added:
            fpr.robots.unregister("fpr3")


@pytest.fixture(scope="module")
def closed(robot):
    return build_closed_chain(robot)


def random_state(robot, rng):
    """A configuration within 0.3 rad / 0.3 m of the reference pose (ball angles around the level drone's) and a
    random velocity.
    """
    q = np.zeros(robot.nq)
    q[:9] = robot.kind.reference_chain
    q[9:] = robot.kind.level_attitude(q)[9:]
    return q + rng.uniform(-0.3, 0.3, robot.nq), rng.normal(size=robot.nq)


def rotation(axis, angle):
    return pin.utils.rotate(axis, angle)


def test_closed_chain_has_the_minimal_model_s_degrees_of_freedom(closed, robot):
    """A free platform (6), three legs, three free drones (18), three point closures (9 rows): 18 = n."""
    assert closed.model.nv == 27 and len(closed.constraints) == 3
    assert closed.model.nv - sum(c.residualSize() for c in closed.constraints) == robot.nq
    assert closed.placed_freeflyers and closed.model.joints[closed.placed_freeflyers[0][0]].shortname() \
        == "JointModelFreeFlyer"


def test_reading_round_trips(closed, robot):
    """minimal -> closed -> minimal at random states, with and without a reference; the loop is closed."""
    rng = np.random.default_rng(SEED)
    for _ in range(10):
        q, v = random_state(robot, rng)
        qc, vc = closed.from_minimal(q, v)
        assert closed.closure_error(qc) < 1e-12
        q1, v1 = closed.to_minimal(qc, vc, reference=q + rng.uniform(-0.5, 0.5, robot.nq))
        np.testing.assert_allclose(q1, q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(v1, v, rtol=0, atol=1e-12)
        np.testing.assert_allclose(closed.to_minimal(qc), q, rtol=0, atol=1e-12)  # the default ranges hold q


def test_reading_unwraps_to_the_reference(closed, robot):
    """Angles read 2 pi away come back within pi of the reference, the ball's other solution included."""
    rng = np.random.default_rng(SEED + 1)
    q, _ = random_state(robot, rng)
    qc = closed.from_minimal(q)
    shifted = q.copy()
    shifted[3:] += 2 * np.pi * rng.integers(-2, 3, robot.nq - 3)
    np.testing.assert_allclose(closed.to_minimal(qc, reference=shifted), shifted, rtol=0, atol=1e-12)


def test_ball_angles_of_inverts_the_chart():
    rng = np.random.default_rng(SEED + 2)
    for _ in range(20):
        pitch, yaw, roll = rng.uniform(-1.4, 1.4, 3)
        rel = rotation("y", pitch) @ rotation("z", yaw) @ rotation("x", roll)
        np.testing.assert_allclose(ball_angles_of(rel), [pitch, yaw, roll], rtol=0, atol=1e-12)
        other = [pitch + np.pi, np.pi - yaw, roll + np.pi]
        np.testing.assert_allclose(ball_angles_of(rel, other), other, rtol=0, atol=1e-12)


def test_constrained_dynamics_agree_with_the_minimal_model(closed, robot):
    """Same state, same thrusts and torques: pin.constraintDynamics on the free platform, the legs and the three
    free drones closed at the balls gives the minimal model's motion (drone twists' derivatives, joint
    accelerations). Two formulations: a tree of 18 joints in one, 4 free flyers and 3 hinges with 9 closure rows
    in the other; the ball's rings ride on the leg in the closed chain (1e-12 kg m^2 left out).
    """
    rng = np.random.default_rng(SEED + 3)
    for _ in range(10):
        q, v = random_state(robot, rng)
        thrust, torque = rng.uniform(3, 15, 3), 0.3 * rng.normal(size=(3, 3))
        a = robot.forward_dynamics(q, v, thrust, torque)
        qc, vc, expected = closed.from_minimal(q, v, a)
        ac = closed.forward_dynamics(qc, vc, closed.generalized_input(qc, thrust, torque))
        np.testing.assert_allclose(ac, expected, rtol=0, atol=1e-9 * (1 + np.abs(expected).max()))


@pytest.mark.skipif(native.use("plant") is None, reason="the native plant is not built")
def test_native_plant_steps_are_the_python_ones(robot):
    """The compiled plant (free flyers, revolute legs, 3D closures) steps the spatial FPR as the Python RKMK4."""
    rng = np.random.default_rng(SEED + 4)
    q, v = random_state(robot, rng)
    w = rng.uniform(400.0, 600.0, (3, 4))
    a = Plant.from_minimal(robot, q, v, w=w)
    b = Plant.from_minimal(robot, q, v, w=w)
    assert a._step_kernel() is not None
    a.advance(w * 1.02, 1e-3, 20)
    with native.switched(plant=False):
        assert b._step_kernel() is None
        b.advance(w * 1.02, 1e-3, 20)
    np.testing.assert_allclose(a.qc, b.qc, rtol=0, atol=1e-10)
    np.testing.assert_allclose(a.vc, b.vc, rtol=0, atol=1e-8)


def test_force_attitude_points_each_thrust_axis_along_its_force(robot):
    """At a random pose, the drones' z axes with the ball angles of force_attitude are along F_i, and the inner
    loop's targets at that state are the measured ball angles, its thrusts |F_i|.
    """
    rng = np.random.default_rng(SEED + 5)
    control = robot.kind._control
    for _ in range(5):
        q, v = random_state(robot, rng)
        force = rng.normal(size=(3, 3)) + [0.0, 0.0, 10.0]
        q[9:] = robot.kind.force_attitude(force, q)
        axes = control.thrust_axes(q)
        np.testing.assert_allclose(axes, force / np.linalg.norm(force, axis=1, keepdims=True), rtol=0, atol=1e-12)
        reference = Reference(np.zeros((5, 9)), np.arange(9.0), -np.arange(9.0))
        targets = robot.kind.attitude_targets(q, v, force, reference, None)
        np.testing.assert_allclose(targets.thrust, np.linalg.norm(force, axis=1), rtol=1e-12)
        np.testing.assert_allclose(targets.target, q[9:], rtol=0, atol=1e-12)
        assert targets.rate == list(range(9)) and targets.pitch == 0.0
        assert np.all(np.asarray(targets.target)[1::3] == 0.0)  # the rule's yaw


def test_level_attitude_puts_every_drone_upright(robot):
    rng = np.random.default_rng(SEED + 6)
    q, _ = random_state(robot, rng)
    level = robot.kind.level_attitude(q)
    np.testing.assert_array_equal(level[:9], q[:9])
    np.testing.assert_allclose(robot.kind._control.thrust_axes(level), np.tile([0.0, 0.0, 1.0], (3, 1)), atol=1e-12)


def _planned(controller, motion):
    """The planning model's thrust vectors F (3, 3) and the drones' ball angles along them at a chain motion's
    sample (5, 9): F = J_h^-T (M_s s'' + c_s).
    """
    robot = controller.robot
    m, c, jac = controller._point_dynamics(motion[0], motion[1])
    force = np.linalg.solve(jac.T, m.dot(motion[2]) + c).reshape(3, 3)
    q = np.zeros(robot.nq)
    q[:9] = motion[0]
    return force, robot.kind.force_attitude(force, q)


def _fly(robot, motion, seconds):
    """The closed loop (the plant at 1 kHz, the controller's inner loop at 500 Hz) along ``motion(t)`` (5, 9), the
    ball angles' feed-forward by central differences of the planned ball angles. Returns the largest
    |s - s_d| of each chain coordinate and the largest closure error.
    """
    controller = CascadedController(robot)
    force, attitude = _planned(controller, motion(0.0))
    q0 = np.zeros(robot.nq)
    q0[:9], q0[9:] = motion(0.0)[0], attitude
    w = np.sqrt([rotor.speeds_squared(np.linalg.norm(f), np.zeros(3))
                 for rotor, f in zip(robot.rotors, force, strict=True)])
    plant = Plant.from_minimal(robot, q0, w=w)
    h, worst, closure = 1e-4, np.zeros(9), 0.0
    for k in range(int(round(seconds / 2e-3))):
        t = 2e-3 * k
        q, v, _, error = plant.observe()
        sample = motion(t)
        worst, closure = np.maximum(worst, np.abs(q[:9] - sample[0])), max(closure, error)
        before, now, after = (_planned(controller, motion(t + d))[1] for d in (-h, 0.0, h))
        reference = Reference(sample, (after - before) / (2 * h), (after - 2 * now + before) / h**2,
                              _planned(controller, sample)[0])
        plant.advance(controller.update(t, q, v, reference).speeds, 1e-3, 2)
    return worst, closure


def test_closed_loop_holds_the_hover(robot):
    """At the reference pose with the hover thrusts (each drone tilted inward along its F_i), the closed loop
    holds still for 2 s.
    """
    s0 = np.array(robot.kind.reference_chain)

    def still(t):
        motion = np.zeros((5, 9))
        motion[0] = s0
        return motion

    worst, closure = _fly(robot, still, 2.0)
    assert worst.max() < 1e-9 and closure < 1e-9


def test_closed_loop_tracks_a_smooth_motion(robot):
    """A smooth 4 s motion of every chain coordinate (0.3 m, 0.5 rad of yaw, 0.2 rad of tilt, legs +-0.2 rad):
    the closed loop tracks it within 3 mm and 3 mrad (0.7 mm and 0.7 mrad when written).
    """
    s0 = np.array(robot.kind.reference_chain)
    amp = np.array([0.3, -0.2, 0.2, 0.5, 0.2, -0.15, 0.2, -0.1, 0.15])
    omega = 2 * np.pi / 4.0

    def motion(t):
        c, s = np.cos(omega * t), np.sin(omega * t)
        return np.array([s0 + amp * (1 - c) / 2, amp * omega * s / 2, amp * omega**2 * c / 2,
                         -amp * omega**3 * s / 2, -amp * omega**4 * c / 2])

    worst, closure = _fly(robot, motion, 4.0)
    assert worst.max() < 3e-3, worst
    assert closure < 1e-6


# ------------------------------------------------------------------------------------------ simulation and scene
@pytest.fixture(scope="module")
def flown(robot):
    """A short rest-to-rest motion of the platform and legs (up, across, yawed and tilted, back) as a plan, and its
    closed-loop simulation by :func:`fpr.sim.closed_loop.simulate`.
    """
    from types import SimpleNamespace

    from fpr.sim.closed_loop import SimulationSettings, simulate
    from planners.trajectory.polynomial import PiecewisePolynomial

    s0 = np.array(robot.kind.reference_chain)
    points = np.zeros((3, 5, 9))
    points[0, 0] = points[2, 0] = s0
    points[1, 0] = s0 + [0.5, 0.2, 0.3, 0.6, 0.2, -0.1, 0.1, -0.1, 0.1]
    result = SimpleNamespace(robot=robot, trajectory=PiecewisePolynomial(points, np.array([2.5, 2.5])),
                             is_way=np.array([True, True, True]), method="none")
    return result, simulate(result, SimulationSettings(hold=0.2))


def test_simulate_tracks_a_rest_to_rest_motion(flown, robot):
    """The simulator's closed loop (the plan's ball-angle feed-forward from the kind's motion_inputs) on the
    spatial FPR: within 2 mm and 2 mrad (0.9 mm and 0.9 mrad when written), the loop closed to 1e-9 m.
    """
    _, log = flown
    assert log.failure is None
    error = np.abs(log.tracking_error)
    assert error[:, :3].max() < 2e-3 and error[:, 3:].max() < 2e-3, error.max(axis=0)
    assert log.closure_error.max() < 1e-9
    assert log.attitude_desired.shape == (log.t.size, 9) and log.planned_attitude.shape == (log.t.size, 9)
    assert log.summary()["max_abs_out_of_plane"] == {}


def test_scene_shows_platform_legs_drones_and_the_plan_as_a_ghost(flown, robot):
    """The meshcat scene of the simulation: the robot's bodies with an axle on every revolute joint along its axis,
    the ghost where the plan puts the drones, the platform's path (its task frame: no 'end_effector' link).
    """
    pin_model = robot.model
    from fpr.views.scene import view

    plan, log = flown
    scene = view(robot, plan, log, fps=FPS)
    paths = set(scene.paths)
    expected = {f"/meshcat/{who}/{j}" for who in ("robot", "ghost")
                for j in ("q1", "q2", "q3", "drone_1_hinge", "drone_3_hinge", "drone_2_ball_pitch")}
    expected |= {f"/meshcat/paths/{p}/{part}" for p in ("planned", "tracked") for part in ("platform", "drone_3")}
    assert expected <= paths
    # an axle on each leg hinge (axis z of its joint frame) and on the ball's pitch joint (axis y)
    for joint, axis in (("q2", 2), ("drone_1_ball_pitch", 1), ("drone_1_hinge", 0)):
        node = {c["name"]: c for c in scene.object(f"robot/{joint}")["object"]["children"]}["hinge"]
        matrix = np.array(node["matrix"]).reshape(4, 4).T  # three.js: column-major
        direction = matrix[:3, :3] @ [0.0, 1.0, 0.0]  # the cylinder's own axis (three.js: y) in the joint frame
        assert abs(direction[axis]) == pytest.approx(1.0, abs=1e-12), (joint, direction)
    assert pin_model.joints[pin_model.getJointId("q2")].shortname() == "JointModelRZ"
    # the ghost's drones where the plan's chain and ball angles put them
    t, ghost = scene.track("ghost/drone_3_hinge", "position")
    q = np.zeros((t.size, robot.nq))
    q[:, :9] = plan.trajectory.evaluate_held(t, order=0)[0]
    forces = robot.kind.motion_inputs(plan.trajectory.evaluate_held(t, order=6)).thrust_vector
    q[:, 9:] = np.stack([robot.kind.force_attitude(f, qk) for f, qk in zip(forces, q, strict=True)])
    for k in range(0, t.size, 20):
        np.testing.assert_allclose(ghost[k], robot.hinge_positions(q[k])[2], atol=1e-9)


def test_the_live_server_takes_the_spatial_fpr():
    """meshcat's own (headless) server receives the scene of the spatial FPR standing still."""
    import urllib.request

    import fpr
    from fpr.views import scene as scene_module

    visualizer = scene_module.serve(fpr.load("fpr3"))
    try:
        with urllib.request.urlopen(visualizer.url(), timeout=10) as response:
            assert b"main.min.js" in response.read()
        assert "embedded-json" in visualizer.static_html()
    finally:
        process = visualizer.window.server_proc
        process.kill()
        process.wait(timeout=10)
