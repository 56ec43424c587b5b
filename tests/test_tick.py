"""The simulator tick's fast paths: each bit for bit equal to the path it replaces.

* :meth:`fpr.sim.plant.Plant.advance` (a tick's plant steps in one call, the command saturated once) against
  the same number of :meth:`~fpr.sim.plant.Plant.step` calls, on a fresh twin plant: the same state bits,
  also with wind (where it is the steps themselves) and for a plant whose ``step`` is overridden (a
  subclass's own step must run at every step);
* a non-finite state stops :meth:`~fpr.sim.plant.Plant.advance` at the same step as :meth:`step`, the
  plant keeping its last finite state;
* the logged kinematics (``Plant._positions_and_closure``, each joint placement read once as a 4x4 matrix)
  against :meth:`~fpr.sim.plant.Plant.drone_positions` and :meth:`~fpr.sim.plant.Plant.closure_error`,
  Pinocchio's own frame placements and SE3 products.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import near_hover

import fpr
from fpr.sim.plant import Plant, PlantDivergedError

DT = 1e-3


def _twins(name, seed):
    """Two equal plants near hover with a random velocity, and a command 5 % off hover with one rotor above
    w_max (so that the saturation matters).
    """
    robot = fpr.load(name)
    q, v, w, command, _ = near_hover(robot, seed)
    command[0, 0] = 1.5 * robot.rotor_constants.max_speed
    plants = [Plant.from_minimal(robot, q, v, w=w) for _ in range(2)]
    return robot, plants, command


def _same_state(a: Plant, b: Plant) -> None:
    assert np.array_equal(a.qc, b.qc) and np.array_equal(a.vc, b.vc)
    assert np.array_equal(a.rotor_speeds, b.rotor_speeds) and a.time == b.time


@pytest.mark.parametrize("name", fpr.ROBOTS)
@pytest.mark.parametrize("wind", [None, (0.4, -0.2, 0.1)])
def test_advance_is_the_steps_bit_for_bit(name, wind):
    """5 ticks of 2 steps: advance and step leave the same bits (state, rotor speeds, time)."""
    _, (fast, slow), command = _twins(name, 3)
    for _ in range(5):  # 5 ticks of 2 steps
        fast.advance(command, DT, 2, wind)
        for _ in range(2):
            slow.step(command, DT, wind)
    _same_state(fast, slow)
    assert abs(fast.time - 10 * DT) < 1e-15
    assert np.abs(fast.vc).max() > 0.1  # it moved


def test_advance_runs_an_overridden_step_at_every_step():
    """A subclass's step (e.g. the gusts' ForcedPlant) is not bypassed by the lean path."""
    calls = []

    class Counted(Plant):
        def step(self, w_command, dt, wind=None):
            calls.append(self.time)
            super().step(w_command, dt, wind)

    robot, (plain, _), command = _twins("fpr", 4)
    counted = Counted(plain.closed, plain.qc, plain.vc, plain.rotor_speeds, reference=plain.measure()[0])
    counted.advance(command, DT, 3)
    plain.advance(command, DT, 3)
    assert calls == [0.0, DT, 2 * DT]
    _same_state(counted, plain)


def test_advance_stops_where_step_does():
    """A command that makes the state non-finite: advance raises at the same step as step, and the plant
    keeps its last finite state.
    """
    robot, (fast, slow), _ = _twins("prototype", 5)
    command = np.full((robot.n_drones, 4), np.nan)  # NaN passes the saturation and poisons the state
    with pytest.raises(PlantDivergedError) as fast_error:
        fast.advance(command, DT, 2)
    with pytest.raises(PlantDivergedError) as slow_error:
        slow.step(command, DT)
    assert fast_error.value.time == slow_error.value.time == 0.0
    _same_state(fast, slow)
    assert np.isfinite(fast.qc).all() and fast.time == 0.0


@pytest.mark.parametrize("name", fpr.ROBOTS)
def test_logged_kinematics_is_pinocchios(name):
    """The drones' centres and the closure error from the 4x4 placements equal Pinocchio's frames and SE3s."""
    _, (plant, _), command = _twins(name, 6)
    plant.advance(command, DT, 20)
    positions, closure = plant.drone_positions_and_closure_error()
    np.testing.assert_allclose(positions, plant.drone_positions(), rtol=0, atol=1e-15)
    assert abs(closure - plant.closure_error()) <= 1e-15
    assert closure > 0.0  # the closure drifts a little: the comparison is not of zeros
