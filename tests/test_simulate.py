"""Closed-loop tracking of planned motions on the closed-chain plant (issue: controller + simulator).

Bounds, and why:
* nominal square: the controller's model is the plant's, except the drones' offset d = 0.1 m,
  which the planning model ignores: the perturbation p_i of eq. 2.7-2.8 (~m d phi'' ~ 0.1 N) acting
  on chain error dynamics with w = 3 rad/s gives errors of a few millimetres; we require < 1 cm
  (m) and < 0.01 rad, and < 1 mm / 1 mrad at the end of the hold (the motion is at rest).
* out of the plane: nothing excites x, psi, theta in a perfect model; the only sources are
  round-off and the closure's numerics, so < 1e-5 (m, rad).
* masses off by 10 %: a 10 % weight error is ~1.2 N per drone; the integral term removes it, the
  transient while it builds up stays < 10 cm and the final error < 5 mm.
* a lost robot (fpr.sim.watch): the simulation stops at the first inner-loop tick (2 ms) past a bound, so
  a failure time is checked against its physics within one tick: zero thrust is an exact free fall
  (the rotors make no force at all from t = 0, no motor lag), a bound lowered under what the plan
  reaches fires where the plan crosses it.
"""

from __future__ import annotations

import numpy as np
import pytest

from fpr.model.errors import ModelArgumentError
from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from fpr.sim.closed_loop import SimulationLog, SimulationSettings, simulate
from planners.missions.mission import load_mission
from planners.optimize import plan


@pytest.fixture(scope="module")
def square_plan():
    return plan(load_mission("square"), "two-step")


@pytest.fixture(scope="module")
def square_log(square_plan):
    return simulate(square_plan, SimulationSettings(hold=1.0))


TICK = 1.0 / SimulationSettings().controller.inner_rate  # the watch looks at every inner-loop tick [s]
G = 9.81


@pytest.fixture(scope="module")
def stopping_square():
    """The square stopping at every way point (no optimisation: quick to plan)."""
    return plan(load_mission("square"), "none")


def test_square_is_tracked(square_log, square_plan):
    log = square_log
    assert log.failure is None and log.failure_time is None and log.summary()["failure"] is None
    assert log.t[-1] == pytest.approx(square_plan.trajectory.total_duration + 1.0)
    err = np.abs(log.tracking_error)
    assert err[:, :2].max() < 0.01 and err[:, 2:].max() < 0.01
    assert np.abs(log.tracking_error[-1]).max() < 1e-3
    summary = log.summary()
    assert max(summary["max_abs_out_of_plane"].values()) < 1e-5
    # the rotors never exceed the planning limit in the plant, and the allocation never saturates
    assert log.speed.max() <= log.speed_limit and log.speed.min() >= 0.0
    assert summary["saturated_ticks"] == 0
    # the log follows the plan in time, and the plant's chain stays closed
    np.testing.assert_allclose(log.reference[0][0], square_plan.trajectory.points[0, 0], atol=1e-12)
    assert log.closure_error.max() < 1e-6


def test_error_converges_from_an_initial_offset(square_plan):
    log = simulate(square_plan, SimulationSettings(initial_error={"y": 0.05, "phi": 0.05}, hold=1.0))
    err = np.abs(log.tracking_error)
    assert err[0, 0] == pytest.approx(0.05, abs=1e-9) and err[0, 2] == pytest.approx(0.05, abs=1e-9)
    late = log.t > 4.0  # error poles at -1, -1, -4 rad/s
    assert err[late].max() < 0.01
    assert np.abs(log.tracking_error[-1]).max() < 2e-3  # the integral's slow pole is still settling


@pytest.mark.parametrize("scale", [1.1, 0.9])
def test_square_tracked_with_masses_off_by_ten_percent(square_plan, scale):
    log = simulate(square_plan, SimulationSettings(model_mass_scale=scale, hold=1.0))
    err = np.abs(log.tracking_error)
    assert err.max() < 0.1
    assert np.abs(log.tracking_error[-1]).max() < 5e-3
    assert log.speed.max() <= log.max_speed


def test_prototype_tour_is_tracked():
    result = plan(load_mission("prototype-tour"), "two-step")
    log = simulate(result, SimulationSettings(hold=0.5))
    assert log.failure is None
    err = np.abs(log.tracking_error)
    assert err.max() < 0.01
    assert np.abs(log.tracking_error[-1]).max() < 1e-3
    assert max(log.summary()["max_abs_out_of_plane"].values()) < 1e-5
    assert log.speed.max() <= log.speed_limit and log.summary()["saturated_ticks"] == 0


def test_saturation_is_reported_and_rotors_stay_within_limits():
    """A motion the rotors cannot fly (square in 1 s per side, stopping at the way points: w^2 < 0 is
    asked at some instants): the allocation clips at the bounds and says so; nothing exceeds w_max. The
    robot does not follow: it is lost within the first side (a drone tipped over or q21 1 rad off its plan),
    where the simulation stops.
    """
    fast = plan(load_mission("square").replace(times=[1.0] * 4), "none")
    assert fast.report.constraints["rotor_speed_low_1"].margin < 0
    log = simulate(fast, SimulationSettings(hold=0.0))
    assert log.failure.startswith(("drone", "tracking lost on q21")) and 0.3 < log.failure_time < 1.0
    assert log.summary()["saturated_ticks"] > 0
    assert log.speed_command.min() >= 0.0 and log.speed_command.max() <= log.max_speed
    assert log.speed.min() >= 0.0 and log.speed.max() <= log.max_speed + 1e-9


def test_log_round_trip(tmp_path, square_log):
    path = tmp_path / "log.npz"
    square_log.save(path)
    back = SimulationLog.load(path)
    assert back.robot_name == "fpr" and back.chain == square_log.chain
    np.testing.assert_array_equal(back.q, square_log.q)
    np.testing.assert_array_equal(back.saturated, square_log.saturated)
    assert back.summary()["tracking_max"] == square_log.summary()["tracking_max"]
    assert back.failure is None and back.failure_time is None


def test_rates_must_divide():
    with pytest.raises(ModelArgumentError, match="integer multiple"):
        simulate(plan(load_mission("study"), "none"), SimulationSettings(plant_rate=750.0))


def assert_stopped_at_failure(log, start):
    """The log ends at the failure's tick, which is named in the message."""
    assert log.failure is not None and log.failure.startswith(start), log.failure
    assert log.t[-1] == pytest.approx(log.failure_time, abs=1e-12)
    assert f"at t = {log.failure_time:.3f} s" in log.failure
    assert log.q.shape[0] == log.t.size == log.reference.shape[1] == log.speed.shape[0]
    summary = log.summary()
    assert summary["failure"] == log.failure and summary["failure_time_s"] == log.failure_time


def test_zero_thrust_is_a_free_fall_stopped_by_the_tracking_bound(stopping_square):
    """Rotors without thrust: the robot falls freely; the planned z stays 0 on the first side, so the z error
    passes 1 m at sqrt(2 / g) = 0.4515 s.
    """
    log = simulate(stopping_square, SimulationSettings(rotor_constant_scale=0.0))
    assert_stopped_at_failure(log, "tracking lost on z")
    expected = np.sqrt(2 * 1.0 / G)
    assert expected <= log.failure_time <= expected + TICK
    z = log.column("z")
    np.testing.assert_allclose(z, -0.5 * G * log.t**2, atol=1e-6)  # free fall of the whole chain
    assert log.thrust.min() > 0  # the controller, unaware, still asks for thrust


def test_zero_thrust_ends_below_the_ground(stopping_square):
    """With a tracking bound out of the way, the lowest drone hinge reaches the ground minus its tolerance
    after an exact free fall: t = sqrt(2 h / g), h from its start height.
    """
    settings = SimulationSettings(rotor_constant_scale=0.0, max_tracking_error=10.0)
    log = simulate(stopping_square, settings)
    assert_stopped_at_failure(log, "drone ")
    assert "hinge below the ground" in log.failure
    robot = stopping_square.robot
    hinge_height = robot.kind.drone_joints(log.reference[0, 0])[:, 1].min()
    fall = hinge_height - (robot.kind.ground_height - settings.ground_tolerance)
    expected = np.sqrt(2 * fall / G)  # 0.521 s from 0.530 m over a ground at -0.75 m
    assert expected <= log.failure_time <= expected + TICK
    assert log.drone_height.min() > robot.kind.ground_height  # the centres of mass are 0.1 m higher


def test_wind_that_the_rotors_cannot_hold_loses_the_robot(stopping_square):
    """100 N of wind along y on each drone, more than all their rotors can give: the end-effector is blown
    1 m off its path after a time bounded by constant accelerations, the wind alone (upper acceleration)
    and the wind minus every rotor at full thrust (lower), plus the motor lag and one tick.
    """
    robot = stopping_square.robot
    log = simulate(stopping_square, SimulationSettings(wind=(0.0, 100.0, 0.0)))
    assert_stopped_at_failure(log, "tracking lost on y")
    mass = robot.total_mass
    wind = 100.0 * robot.n_drones
    full_thrust = 4 * robot.n_drones * robot.rotor_constants.max_rotor_thrust
    fastest = np.sqrt(2 * 1.0 / (wind / mass))
    slowest = np.sqrt(2 * 1.0 / ((wind - full_thrust) / mass)) + robot.rotor_constants.time_constant + TICK
    assert fastest <= log.failure_time <= slowest
    err = np.abs(log.tracking_error[:, 0])
    assert err[-1] > 1.0 >= err[-2]  # stopped at the first tick past the bound


def test_a_huge_initial_error_is_lost_tracking_at_once(stopping_square):
    log = simulate(stopping_square, SimulationSettings(initial_error={"y": 1.5}))
    assert_stopped_at_failure(log, "tracking lost on y (error 1.5 m > 1 m)")
    assert log.failure_time == 0.0 and log.t.size == 1


def planned_motion(result, duration=3.0):
    """The plan's motion on the first side, at the inner-loop ticks."""
    return result.trajectory.evaluate_held(np.arange(0.0, duration, TICK), order=MOTION_ORDER)


def test_a_drone_faster_than_the_speed_bound(stopping_square):
    """A speed bound under the plan's own: it fires where the planned hinge speed crosses it."""
    robot, bound = stopping_square.robot, 0.2
    log = simulate(stopping_square, SimulationSettings(max_drone_speed=bound))
    assert_stopped_at_failure(log, "drone ")
    assert "diverged (speed" in log.failure and f"> {bound:g} m/s" in log.failure
    motion = planned_motion(stopping_square)
    planned = np.linalg.norm(robot.kind.drone_joint_velocities(motion[0], motion[1]), axis=-1).max(axis=-1)
    crossing = np.argmax(planned > bound) * TICK  # 0.684 s
    assert abs(log.failure_time - crossing) < 0.05  # the tracking lag (measured: 0.670 s)


def test_a_drone_spinning_or_tilting_past_its_bound(stopping_square):
    """Bounds on the drones' angular speed and tilt under the plan's roll rate and roll: each fires where
    the plan crosses it (the robot stays in its plane: tilt = |roll|, angular speed = |roll rate|).
    """
    planned = inverse_dynamics(stopping_square.robot, planned_motion(stopping_square))
    for field, bound, planned_value, word in (
            ("max_drone_rate", 0.2, np.abs(planned.roll_rate).max(axis=1), "angular speed"),
            ("max_tilt", 0.2, np.abs(planned.roll).max(axis=1), "tilt from the vertical")):
        log = simulate(stopping_square, SimulationSettings(**{field: bound}))
        assert_stopped_at_failure(log, "drone ")
        assert f"diverged ({word}" in log.failure, log.failure
        crossing = np.argmax(planned_value > bound) * TICK
        assert abs(log.failure_time - crossing) < 0.05, (field, log.failure_time, crossing)


def test_a_force_no_chain_holds_breaks_the_closure(stopping_square):
    """1e6 N on each drone, up and sideways: the integrator cannot keep the loop closed (its closure
    drift is ~2 cm after the first tick), which the watch reports before the speed it also reaches.
    """
    log = simulate(stopping_square, SimulationSettings(wind=(0.0, 1e6, 1e6)))
    assert_stopped_at_failure(log, "the chain's closure broke (closure error ")
    assert "> 0.001 m" in log.failure
    assert log.failure_time == pytest.approx(TICK) and log.closure_error[-1] > 1e-3 >= log.closure_error[0]


def test_a_state_that_turns_non_finite_ends_the_log(stopping_square):
    """A wind of 1e300 N makes the first plant step non-finite: the log keeps the one finite sample."""
    log = simulate(stopping_square, SimulationSettings(wind=(0.0, 1e300, 0.0)))
    assert log.failure.startswith("the state diverged (the plant state became non-finite"), log.failure
    assert log.t.size == 1 and log.t[-1] <= log.failure_time <= log.t[-1] + TICK
    assert np.isfinite(log.q).all()


def test_failed_log_round_trip(tmp_path, stopping_square):
    log = simulate(stopping_square, SimulationSettings(initial_error={"z": -1.2}))
    path = tmp_path / "failed.npz"
    log.save(path)
    back = SimulationLog.load(path)
    assert back.failure == log.failure and back.failure_time == log.failure_time
    np.testing.assert_array_equal(back.q, log.q)


@pytest.mark.parametrize("field, value", [
    ("rotor_constant_scale", -1.0), ("model_mass_scale", 0.0), ("model_mass_scale", float("nan")),
    ("hold", -1.0), ("plant_rate", 0.0), ("max_tracking_error", 0.0), ("ground_tolerance", float("inf")),
    ("wind", (1.0, 2.0)), ("wind", (0.0, float("nan"), 0.0)), ("measurement_noise", (-0.01, 0.0)),
    ("initial_error", {"y": float("inf")}), ("initial_error", {"bogus": 1.0})])
def test_settings_are_checked(stopping_square, field, value):
    with pytest.raises(ModelArgumentError) as caught:
        simulate(stopping_square, SimulationSettings(**{field: value}))
    assert caught.value.argument in (field, "measurement_noise")
