"""One run of a campaign: the plan flown with one draw of the perturbations, and what came of it.

:class:`Flight` is what every worker receives once: the planned motion (its polynomial trajectory) and the
robot it was planned for (name and parameters; each worker builds the robot itself, once per set of
parameters). :func:`fly` simulates run ``index`` (:func:`fpr.sim.closed_loop.simulate`) and returns its row
(:func:`outcome_row`): a run that raises is a row with its error, never an exception.

Outcomes of a row (the columns after the sampled values):

========================== ==================================================================================
``success``                no error, the robot not lost and, with a tracking tolerance, every planning
                           coordinate within it
``lost``                   the simulator's watch stopped the run (:mod:`fpr.sim.watch`)
``failure``                what happened and when (the watch's line), "" when not lost
``failure_time_s``         when [s] (NaN when not lost)
``error``                  ``Type: message`` of an exception the run raised (a sampled value out of its range,
                           a bug), "" otherwise; the outcome columns are then NaN
``max_error_<c>``          largest |measured - planned| of each planning coordinate [m or rad]
``least_clearance_m``      least height of a drone's centre of mass above the ground [m]
``saturated_ticks``        inner-loop ticks with a rotor at a bound of the allocation
``peak_rotor_speed_rad_s`` the plant's highest rotor speed [rad/s] (w_max = 900)
``simulated_s``            simulated time [s] (shorter than the plan when lost)
========================== ==================================================================================
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from fpr.robots import load
from fpr.robustness.spec import INITIAL_ERROR, SETTINGS
from fpr.sim.closed_loop import SimulationSettings, simulate
from fpr.sim.plant import PlantDivergedError

OUTCOMES = ("success", "lost", "failure", "failure_time_s", "error", "least_clearance_m", "saturated_ticks",
            "peak_rotor_speed_rad_s", "simulated_s")
"""Outcome columns every row has (``max_error_<coordinate>`` columns come after them)."""


@dataclass(frozen=True)
class Flight:
    """The plan shipped to the workers: small, picklable, the same for every run.

    Attributes:
        robot_name: the registered robot (``robot.name``).
        robot_parameters: the robot's parameters the plan was made with (xacro overrides).
        chain: the planning coordinates (``robot.layout.chain``), for the tracking columns.
        trajectory: the planned motion (:class:`planners.trajectory.polynomial.PiecewisePolynomial`).
        hold: time simulated after the plan's end [s].
        tracking_tolerance: see :class:`fpr.robustness.spec.Campaign`.
    """

    robot_name: str
    robot_parameters: tuple
    chain: tuple
    trajectory: object
    hold: float
    tracking_tolerance: float | None = None

    @property
    def columns(self) -> tuple[str, ...]:
        """The outcome columns of a row, in order."""
        return OUTCOMES + tuple(f"max_error_{c}" for c in self.chain)


@dataclass(frozen=True)
class _Plan:
    """What :func:`fpr.sim.closed_loop.simulate` asks of a plan: the robot and the trajectory."""

    robot: object
    trajectory: object


@functools.lru_cache(maxsize=8)
def _robot(name: str, parameters: tuple):
    return load(name, **dict(parameters))


def settings_of(flight: Flight, values: dict, noise_seed: int) -> tuple[SimulationSettings, dict]:
    """The simulation settings of one run and the robot parameters it changes (from its sampled ``values``)."""
    fields = {"hold": flight.hold, "seed": noise_seed}
    wind, noise, initial, parameters = [0.0, 0.0, 0.0], [0.0, 0.0], {}, {}
    for name, value in values.items():
        if name in ("model_mass_scale", "rotor_constant_scale"):
            fields[name] = value
        elif name.startswith("wind_"):
            wind["xyz".index(name[-1])] = value
        elif name.startswith("noise_"):
            noise["qv".index(name[-1])] = value
        elif name.startswith(INITIAL_ERROR):
            initial[name[len(INITIAL_ERROR):]] = value
        elif name not in SETTINGS:
            parameters[name] = value
    return SimulationSettings(initial_error=initial, measurement_noise=tuple(noise), wind=tuple(wind),
                              **fields), parameters


def outcome_row(flight: Flight, log, ground: float) -> dict:
    """The outcomes of a simulation log (see the module docstring); ``ground``: the ground's height [m]."""
    error = np.abs(log.tracking_error)
    lost = log.failure is not None
    row = {
        "lost": lost,
        "failure": log.failure or "",
        "failure_time_s": math.nan if log.failure_time is None else float(log.failure_time),
        "error": "",
        "least_clearance_m": float(log.drone_height.min() - ground) if log.t.size else math.nan,
        "saturated_ticks": int(log.saturated.any(axis=(1, 2)).sum()),
        "peak_rotor_speed_rad_s": float(log.speed.max()) if log.t.size else math.nan,
        "simulated_s": float(log.t[-1] - log.t[0]) if log.t.size else 0.0,
    }
    for j, c in enumerate(flight.chain):
        row[f"max_error_{c}"] = float(error[:, j].max()) if log.t.size else math.nan
    worst = max((row[f"max_error_{c}"] for c in flight.chain), default=0.0)
    row["success"] = not lost and (flight.tracking_tolerance is None or worst <= flight.tracking_tolerance)
    return row


def error_row(flight: Flight, error: BaseException) -> dict:
    """The row of a run that raised ``error``: not a success, outcomes NaN, the error's type and message."""
    message = " ".join(str(error).split())
    row = {"success": False, "lost": False, "failure": "", "failure_time_s": math.nan,
           "error": f"{type(error).__name__}: {message}"[:500], "least_clearance_m": math.nan,
           "saturated_ticks": -1, "peak_rotor_speed_rad_s": math.nan, "simulated_s": 0.0}
    row.update({f"max_error_{c}": math.nan for c in flight.chain})
    return row


def fly(flight: Flight, index: int, values: dict, noise_seed: int) -> dict:
    """Simulate run ``index`` with its sampled ``values``; returns its row (index, values, outcomes).

    Never raises for the run's own sake (an ``Exception`` becomes the row's ``error``); an interruption or a
    dying process does propagate (the engine redoes the run).
    """
    row = {"index": int(index), **values}
    try:
        settings, changed = settings_of(flight, values, noise_seed)
        parameters = {**dict(flight.robot_parameters), **changed}
        robot = _robot(flight.robot_name, tuple(sorted(parameters.items())))
        log = simulate(_Plan(robot, flight.trajectory), settings)
        row.update(outcome_row(flight, log, float(robot.kind.ground_height)))
    except PlantDivergedError as error:  # diverged before a log could be made: lost at once
        row.update(error_row(flight, error), lost=True, error="", failure=" ".join(str(error).split()))
    except Exception as error:  # noqa: BLE001 - a failed run is a row with its error
        row.update(error_row(flight, error))
    return row
