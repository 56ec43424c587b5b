"""The controller's and the simulator's hooks in the robot kind: the inner loop's targets
(``kind.attitude_targets``), the lateral loop (``kind.lateral_loop``, from ``out_of_plane``), the compiled inner
loop's constants (``kind.compiled_inner_constants``), the take-off leveling (``kind.level_attitude``), and the
attitude names of ``Reference``, ``ControlOutput`` and ``SimulationLog`` with their former names as aliases.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import near_hover

import fpr
from controllers.ctc import CascadedController, ControllerSettings, Reference
from fpr import _native as native
from fpr.model.robot import Robot
from fpr.sim.closed_loop import SimulationLog


@pytest.fixture(scope="module", params=["fpr", "prototype"])
def robot(request):
    return fpr.load(request.param)


def _reference(robot, rng):
    n_s, n_d = len(robot.layout.chain), robot.n_drones
    return Reference(rng.normal(size=(5, n_s)), rng.normal(size=n_d), rng.normal(size=n_d))


def _with_kind(robot, **members):
    """The same robot with a subclass of its kind that has ``members``."""
    kind = type("Changed", (type(robot.kind),), members)
    return Robot(kind, robot.urdf, robot.parameters)


def test_planar_attitude_targets_are_the_roll_along_the_force_and_the_thrust_along_the_drone_axis(robot):
    rng = np.random.default_rng(4)
    settings = ControllerSettings()
    rolls = robot.indices(robot.layout.rolls)
    md = np.array(robot.drone_masses) * np.array(robot.hinge_offsets)
    for _ in range(20):
        q, v = rng.normal(scale=2.0, size=robot.nq), rng.normal(size=robot.nq)
        force = rng.normal(scale=10.0, size=(robot.n_drones, 2))
        reference = _reference(robot, rng)
        out = robot.kind.attitude_targets(q, v, force, reference, settings)
        n_a = len(robot.layout.attitude)
        assert len(out.target) == len(out.rate) == len(out.acceleration) == n_a
        assert len(out.thrust) == robot.n_drones
        # independently: the roll whose thrust axis (-sin phi, cos phi) is along F, and F's component on the
        # measured axis less the offset's centripetal term
        roll = np.arctan2(-force[:, 0], force[:, 1])
        axis = np.stack([-np.sin(roll), np.cos(roll)], axis=-1)
        np.testing.assert_allclose(np.sum(axis * force, axis=-1), np.linalg.norm(force, axis=-1), rtol=1e-12)
        measured_axis = np.stack([-np.sin(q[rolls]), np.cos(q[rolls])], axis=-1)
        thrust = np.sum(measured_axis * force, axis=-1) - md * v[rolls] ** 2
        np.testing.assert_allclose(out.thrust, thrust, rtol=1e-12, atol=1e-12)
        places = [robot.layout.attitude.index(c) for c in robot.layout.rolls]
        np.testing.assert_allclose(np.array(out.target)[places], roll, rtol=1e-15)
        np.testing.assert_array_equal(np.array(out.rate)[places], reference.attitude_rate)
        np.testing.assert_array_equal(np.array(out.acceleration)[places], reference.attitude_acceleration)
        others = [k for k in range(n_a) if k not in places]  # psi, theta: 0 but the lateral loop's pitch
        theta = robot.layout.attitude.index("theta")
        assert [out.target[k] for k in others if k != theta] == [0.0]
        assert out.target[theta] == out.pitch
        assert [out.rate[k] for k in others] == [0.0, 0.0] and [out.acceleration[k] for k in others] == [0.0, 0.0]
        assert abs(out.pitch) <= settings.max_pitch


def test_the_lateral_loop_holds_x_with_the_pitch_for_a_kind_with_x_out_of_the_plane(robot):
    loop = robot.kind.lateral_loop
    if "x" not in robot.kind.out_of_plane:
        assert loop is None
        q, v, force = np.zeros(robot.nq), np.ones(robot.nq), np.ones((robot.n_drones, 2))
        reference = _reference(robot, np.random.default_rng(1))
        out = robot.kind.attitude_targets(q, v, force, reference, ControllerSettings())
        assert out.pitch == 0.0
        return
    x, gain = loop
    assert x == robot.index["x"]
    # the sensitivity d x'' / d theta by a central difference of another step, at the same hover
    from fpr.sim.plant import hover_configuration

    q0 = hover_configuration(robot, robot.kind.reference_chain)
    s0 = np.array(robot.kind.reference_chain)
    hover = robot.kind.motion_inputs(np.concatenate([s0[None, None], np.zeros((4, 1, s0.size))]))
    acc = []
    for sign in (1, -1):
        q = q0.copy()
        q[robot.index["theta"]] = sign * 1e-4
        acc.append(robot.forward_dynamics(q, np.zeros(robot.nq), hover.thrust[0], hover.torque[0])[x])
    assert gain == pytest.approx((acc[0] - acc[1]) / 2e-4, rel=1e-4)
    assert abs(gain) > 1.0  # a real coupling: a pitch moves x
    # x off to one side: the pitch pushes it back (x'' = gain theta against x), clamped at max_pitch far off
    settings = ControllerSettings()
    q, v = np.zeros(robot.nq), np.zeros(robot.nq)
    force = np.ones((robot.n_drones, 2))
    reference = _reference(robot, np.random.default_rng(2))
    q[x] = 0.01
    pitch = robot.kind.attitude_targets(q, v, force, reference, settings).pitch
    assert gain * pitch < 0 and abs(pitch) < settings.max_pitch
    q[x] = 100.0
    assert abs(robot.kind.attitude_targets(q, v, force, reference, settings).pitch) == settings.max_pitch


def test_the_lateral_loop_follows_out_of_plane_not_the_coordinate_names():
    robot = fpr.load("fpr")
    assert robot.kind.lateral_loop is not None
    pinned = _with_kind(robot, out_of_plane=("psi", "theta"))
    assert "x" in pinned.layout.coordinates and pinned.kind.lateral_loop is None
    controller = CascadedController(pinned)
    assert not controller.lateral
    q, v, *_ = near_hover(pinned, 3)
    q[pinned.index["x"]] = 0.5
    reference = _reference(pinned, np.random.default_rng(3))
    reference.motion[0] = q[pinned.indices(pinned.layout.chain)]
    for inner in (True, False):
        with native.switched(inner=inner):
            assert CascadedController(pinned).update(0.0, q, v, reference).pitch_desired == 0.0
    assert CascadedController(robot).update(0.0, q, v, reference).pitch_desired != 0.0


def test_the_attitude_gains_follow_the_drones_attitude_coordinates(robot):
    st = ControllerSettings(orientation_frequency=2.0, attitude_frequency=20.0)
    controller = CascadedController(robot, st)
    kp, kd = controller._attitude_gains()
    drone = [c in robot.layout.rolls for c in robot.layout.attitude]
    np.testing.assert_array_equal(kp, np.where(drone, 400.0, 4.0))
    np.testing.assert_array_equal(kd, np.where(drone, 40.0, 4.0))


def test_the_compiled_inner_loop_is_used_only_for_the_default_targets(robot):
    assert robot.kind.compiled_inner_constants(ControllerSettings()) is not None
    shift = 0.1

    def attitude_targets(self, q, v, force, reference, settings):
        out = type(robot.kind).attitude_targets(self, q, v, force, reference, settings)
        moved = [t + shift if c in self.layout.rolls else t for c, t in zip(self.layout.attitude, out.target,
                                                                             strict=True)]
        return out._replace(target=moved)

    changed = _with_kind(robot, attitude_targets=attitude_targets)
    assert changed.kind.compiled_inner_constants(ControllerSettings()) is None
    q, v, *_ = near_hover(robot, 5)
    reference = _reference(robot, np.random.default_rng(5))
    reference.motion[0] = q[robot.indices(robot.layout.chain)]
    with native.switched(inner=True):  # the switch on: the override still runs (in Python)
        controller = CascadedController(changed)
        assert controller._inner_kernel() is None
        a = controller.update(0.0, q, v, reference)
    with native.switched(inner=False):
        b = CascadedController(robot).update(0.0, q, v, reference)
    np.testing.assert_allclose(a.attitude_target, b.attitude_target + shift, rtol=1e-12)
    # the attitude loop on the moved target: u_a of the rolls lower by K_pa times the shift
    kp = CascadedController(robot)._attitude_gains()[0]
    places = [robot.layout.attitude.index(c) for c in robot.layout.rolls]
    np.testing.assert_allclose(a.attitude_desired[places] - b.attitude_desired[places], kp[places] * shift,
                               rtol=1e-6)


def test_the_controller_ticks_on_the_kind_s_targets_and_its_outputs_have_the_force_axes(robot):
    q, v, *_ = near_hover(robot, 7)
    reference = _reference(robot, np.random.default_rng(7))
    reference.motion[0] = q[robot.indices(robot.layout.chain)]
    controller = CascadedController(robot)
    with native.switched(inner=False):
        out = controller.update(0.0, q, v, reference)
    assert out.force.shape == (robot.n_drones, len(robot.kind.force_axes))
    expected = robot.kind.attitude_targets(q, v, out.force, reference, controller.settings)
    np.testing.assert_array_equal(out.thrust_desired, expected.thrust)
    places = [robot.layout.attitude.index(c) for c in robot.layout.rolls]
    np.testing.assert_array_equal(out.attitude_target, np.array(expected.target)[places])
    assert out.pitch_desired == expected.pitch


def test_level_attitude_sets_the_drones_level_on_a_copy(robot):
    q = np.random.default_rng(8).normal(size=robot.nq)
    level = robot.kind.level_attitude(q)
    rolls = robot.indices(robot.layout.rolls)
    assert (level[rolls] == 0.0).all() and (q[rolls] != 0.0).all()
    others = np.setdiff1d(np.arange(robot.nq), rolls)
    np.testing.assert_array_equal(level[others], q[others])


def test_the_former_attitude_names_are_aliases(robot):
    rng = np.random.default_rng(9)
    reference = _reference(robot, rng)
    assert reference.roll_rate is reference.attitude_rate
    assert reference.roll_acceleration is reference.attitude_acceleration
    q, v, *_ = near_hover(robot, 9)
    out = CascadedController(robot).update(0.0, q, v, reference)
    assert out.roll_desired is out.attitude_target


def _small_log(robot, rng, n=4):
    n_d, n_s = robot.n_drones, len(robot.layout.chain)
    return SimulationLog(robot.name, tuple(robot.layout.coordinates), tuple(robot.layout.chain), np.arange(n) * 0.01,
                         rng.normal(size=(n, robot.nq)), rng.normal(size=(n, robot.nq)), rng.normal(size=(3, n, n_s)),
                         rng.normal(size=(n, n_d)), rng.normal(size=(n, n_d)), rng.normal(size=(n, n_d, 4)),
                         rng.normal(size=(n, n_d, 4)), rng.normal(size=(n, n_d)), rng.normal(size=(n, n_d, 3)),
                         np.zeros((n, n_d, 4), dtype=bool), rng.normal(size=(n, n_d)), rng.normal(size=n), 900.0,
                         850.0, 0.1)


def test_simulation_logs_keep_their_file_keys_and_read_either_name(robot, tmp_path):
    log = _small_log(robot, np.random.default_rng(10))
    assert log.planned_roll is log.planned_attitude and log.roll_desired is log.attitude_desired
    path = tmp_path / "log.npz"
    log.save(path)
    with np.load(path) as data:  # the files of every version: the former keys
        assert {"planned_roll", "roll_desired"} <= set(data.files)
        assert not {"planned_attitude", "attitude_desired"} & set(data.files)
    back = SimulationLog.load(path)
    np.testing.assert_array_equal(back.planned_attitude, log.planned_attitude)
    np.testing.assert_array_equal(back.attitude_desired, log.attitude_desired)
    for name in ("q", "v", "reference", "speed", "thrust", "torque", "saturated", "closure_error"):
        np.testing.assert_array_equal(getattr(back, name), getattr(log, name))
    assert dataclasses.replace(back, wall_time=1.0).planned_roll is back.planned_attitude


def test_the_outer_loop_takes_the_world_rows_of_the_kind_s_force_axes():
    from controllers.ctc import _force_rows

    assert _force_rows(("y", "z")) == slice(1, 3)
    assert _force_rows(("x", "y", "z")) == slice(0, 3)
    assert _force_rows(("x", "z")) == [0, 2]
    vector = np.array([1.0, 2.0, 3.0])
    for axes in (("y", "z"), ("x", "y", "z"), ("x", "z")):
        np.testing.assert_array_equal(vector[_force_rows(axes)], ["xyz".index(a) + 1.0 for a in axes])


def test_the_outer_loop_s_known_forces_act_through_the_force_axes_only(robot):
    # a force along x (out of the plane) does nothing to the planar chain; along y it does
    q, v, *_ = near_hover(robot, 11)
    controller = CascadedController(robot)
    s = q[robot.indices(robot.layout.chain)]
    _, _, jac = controller._point_dynamics(s, np.zeros_like(s))
    along_x = np.zeros((robot.n_drones, 3))
    along_x[:, 0] = 5.0
    np.testing.assert_array_equal(controller.external_force([5.0, 0.0, 0.0], along_x, jac), 0.0)
    along_y = np.roll(along_x, 1, axis=1)
    assert np.abs(controller.external_force(None, along_y, jac)).max() > 0.1


def test_force_attitude_is_the_roll_whose_thrust_axis_is_along_the_force(robot):
    force = np.random.default_rng(12).normal(scale=10.0, size=(robot.n_drones, 2))
    roll = robot.kind.force_attitude(force)
    assert roll.shape == (robot.n_drones,)
    axis = np.stack([-np.sin(roll), np.cos(roll)], axis=-1)  # the drone's thrust axis in (y, z)
    np.testing.assert_allclose(axis * np.linalg.norm(force, axis=-1, keepdims=True), force, rtol=1e-12, atol=1e-12)
