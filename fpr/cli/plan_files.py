"""The files of ``python -m fpr.plan``: ``trajectory.csv`` (columns and units in the documentation,
guides/plan-command) and ``plan.json``.

``plan.json`` holds no wall-clock time (:func:`split_timings` moves them into ``manifest.json``), so that the
same command gives the same bytes in ``plan.json`` and ``trajectory.csv``.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from planners.optimize import PlanResult

_TIMING_KEYS = ("wall_time_s", "wall_time")


def csv_columns(robot) -> list[tuple[str, str]]:
    """(name, unit) of every column of ``trajectory.csv`` for ``robot``."""
    coords = list(robot.kind.planning_columns())
    cols = [("t", "s")] + coords + [(n + "_d", u + "/s") for n, u in coords] + [(n + "_dd", u + "/s^2")
                                                                                 for n, u in coords]
    for i in range(1, robot.n_drones + 1):
        angle = robot.kind.drone_angle_column
        cols += [(f"{axis}_j{i}", "m") for axis in robot.kind.force_axes]
        cols += [(f"{angle}{i}", "rad"), (f"{angle}{i}_d", "rad/s"), (f"f{i}", "N"),
                 (f"tau{i}_x", "N m"), (f"tau{i}_y", "N m"), (f"tau{i}_z", "N m")]
        cols += [(f"w{i}_{m}", "rad/s") for m in range(1, 5)]
    return cols


def _simulated_columns(robot, log, t) -> tuple[list[str], np.ndarray]:
    """sim_ columns: the simulated counterparts of the planned ones, interpolated at times t."""
    chain = [log.coordinates.index(c) for c in log.chain]
    s = log.q[:, chain]
    joints = robot.kind.drone_joints(s)
    data = {}
    for c in log.coordinates:
        data[c] = log.q[:, log.coordinates.index(c)]
        data[c + "_d"] = log.v[:, log.coordinates.index(c)]
    for i in range(robot.n_drones):
        for k, axis in enumerate(robot.kind.force_axes):
            data[f"{axis}_j{i + 1}"] = joints[:, i, k]
        data[f"f{i + 1}"] = log.thrust[:, i]
        for k, axis in enumerate("xyz"):
            data[f"tau{i + 1}_{axis}"] = log.torque[:, i, k]
        for m in range(4):
            data[f"w{i + 1}_{m + 1}"] = log.speed[:, i, m]
    names = ["sim_" + n for n in data]
    after = np.nan if getattr(log, "failure", None) else None  # a lost robot: nothing after the log's end
    return names, np.stack([np.interp(t, log.t, v, right=after) for v in data.values()], axis=1)


def write_csv(path: Path, robot, sampled, log=None) -> None:
    """One row per sample of ``sampled`` (a :class:`planners.optimize.SampledPlan`); units in the documentation
    (guides/plan-command).

    With a :class:`fpr.sim.closed_loop.SimulationLog`, the simulated columns follow, prefixed ``sim_`` (empty,
    ``nan``, after the time a lost robot's log stops).
    """
    inputs, motion = sampled.inputs, sampled.motion
    columns = [sampled.t[:, None], motion[0], motion[1], motion[2]]
    for i in range(robot.n_drones):
        columns += [inputs.joint_position[:, i], inputs.roll[:, i:i + 1], inputs.roll_rate[:, i:i + 1],
                    inputs.thrust[:, i:i + 1], inputs.torque[:, i], inputs.rotor_speed[:, i]]
    names = [n for n, _ in csv_columns(robot)]
    if log is not None:
        sim_names, sim_data = _simulated_columns(robot, log, sampled.t)
        names += sim_names
        columns.append(sim_data)
    data = np.hstack(columns)
    assert data.shape[1] == len(names)
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(names)
        writer.writerows(np.round(data, 9).tolist())


def plan_document(mission, robot, result: PlanResult, reference: PlanResult) -> dict:
    """The content of ``plan.json``."""
    trajectory = result.trajectory
    return {
        "mission": mission.to_dict(),
        "method": result.method,
        "robot": {"name": robot.name, "parameters": robot.parameters},
        "summary": result.summary(),
        "reference_summary": reference.summary(),
        "points": trajectory.points.tolist(),
        "points_layout": "points[p][k][j]: k-th time derivative (k = 0..4) of coordinate j at point p",
        "is_way_point": result.is_way.tolist(),
        "durations_s": trajectory.durations.tolist(),
        "knots_s": trajectory.knots.tolist(),
        "coefficients": [seg.coefficients.tolist() for seg in trajectory.segments],
        "coefficients_layout": "coefficients[i][c][j]: s_j(t) = sum_c a[c] (t - knots[i])^c on segment i, SI units",
    }

def split_timings(document, path: str = "") -> dict:
    """Remove every wall-clock time (keys ``wall_time_s``, ``wall_time``) from ``document`` in place.

    Returns:
        the times removed, by their path in the document (``summary``, ``summary.stages.step 1``...) [s].
    """
    found = {}
    if isinstance(document, dict):
        for key in [k for k in document if k in _TIMING_KEYS]:
            found[path or "document"] = document.pop(key)
        for key, value in document.items():
            found.update(split_timings(value, f"{path}.{key}" if path else str(key)))
    elif isinstance(document, list):
        for i, value in enumerate(document):
            name = value.get("name", i) if isinstance(value, dict) else i
            found.update(split_timings(value, f"{path}.{name}"))
    return found
