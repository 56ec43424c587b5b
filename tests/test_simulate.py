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
"""

from __future__ import annotations

import numpy as np
import pytest

from fpr.model.errors import ModelArgumentError
from fpr.sim.closed_loop import SimulationLog, SimulationSettings, simulate
from planners.mission import load_mission
from planners.optimize import plan


@pytest.fixture(scope="module")
def square_plan():
    return plan(load_mission("square"), "two-step")


@pytest.fixture(scope="module")
def square_log(square_plan):
    return simulate(square_plan, SimulationSettings(hold=1.0))


def test_square_is_tracked(square_log, square_plan):
    log = square_log
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
    err = np.abs(log.tracking_error)
    assert err.max() < 0.01
    assert np.abs(log.tracking_error[-1]).max() < 1e-3
    assert max(log.summary()["max_abs_out_of_plane"].values()) < 1e-5
    assert log.speed.max() <= log.speed_limit and log.summary()["saturated_ticks"] == 0


def test_saturation_is_reported_and_rotors_stay_within_limits():
    """A motion the rotors cannot fly (square in 1 s per side, stopping at the way points: w^2 < 0 is
    asked at some instants): the allocation clips at the bounds and says so; nothing exceeds w_max."""
    fast = plan(load_mission("square").replace(times=[1.0] * 4), "none")
    assert fast.report.constraints["rotor_speed_low_1"].margin < 0
    log = simulate(fast, SimulationSettings(hold=0.0))
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


def test_rates_must_divide():
    with pytest.raises(ModelArgumentError, match="integer multiple"):
        simulate(plan(load_mission("study"), "none"), SimulationSettings(plant_rate=750.0))
