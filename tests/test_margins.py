"""Closed-loop margins (fpr.sim.margins): constructed logs whose margins are known by construction.

A log that follows the plan exactly has the plan's own margins (the dense-grid report of planners.problem.report is
an independent computation of the same constraints); the physical margin is the planning one plus the design
margin (m_gd, m_ga, m_gr from the robot's parameters); a log pushed below the ground by a known depth at a
known tick breaks the ground's physical limit by that depth at that time, and the command line then exits 1
with simulation.json naming it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from fpr.cli import contract
from fpr.cli import plan as cli
from fpr.model.errors import ModelArgumentError
from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from fpr.sim.closed_loop import SimulationLog
from fpr.sim.margins import (
    broken,
    broken_message,
    closed_loop_margins,
    eaten,
    margin_series,
    physical_robot,
    simulation_document,
    thrust_floor,
)
from planners.missions.mission import load_mission
from planners.optimize import plan

TICK = 0.002  # [s]


@pytest.fixture(scope="module")
def study_plan():
    return plan(load_mission("study"), "none")


def follow(result, tick: float = TICK) -> SimulationLog:
    """A log whose robot does exactly what the plan says (planned state, rotor speeds and thrusts)."""
    robot = result.robot
    t = np.arange(0.0, result.trajectory.total_duration + 1e-9, tick)
    motion = result.trajectory.evaluate(t, order=MOTION_ORDER)
    planned = inverse_dynamics(robot, motion)
    q, v, _ = planned.full_state(robot)
    n, n_d = len(t), robot.n_drones
    return SimulationLog(robot.name, tuple(robot.layout.coordinates), tuple(robot.layout.chain), t, q, v,
                         motion[:3], planned.roll, planned.roll, planned.rotor_speed, planned.rotor_speed,
                         planned.thrust, planned.torque, np.zeros((n, n_d, 4), bool), np.zeros((n, n_d)),
                         np.zeros(n), robot.rotor_constants.max_speed,
                         robot.rotor_constants.max_speed - robot.margins.rotor_speed, 0.0)


def test_a_log_that_follows_the_plan_has_the_plans_margins(study_plan):
    margins = closed_loop_margins(study_plan, follow(study_plan))
    assert set(margins) == set(study_plan.report.constraints)
    for name, m in margins.items():
        planned = study_plan.report.constraints[name]
        scale = {"m": 1e-3, "rad": 1e-3, "rad/s": 1.0, "N": 1e-2}[m.unit]  # 500 Hz grid vs 2 ms ticks
        assert m.margin_planning == pytest.approx(planned.margin, abs=scale), name
        assert m.planned == planned.margin and m.state == "ok"
    assert not broken(margins) and not eaten(margins) and broken_message(margins) is None


def test_physical_margin_is_the_planning_margin_plus_the_design_margin(study_plan):
    robot = study_plan.robot
    margins = closed_loop_margins(study_plan, follow(study_plan))
    design = {"ground": robot.margins.ground, "phi": robot.margins.angle, "q21": robot.margins.angle,
              "roll": robot.margins.angle, "rotor_speed_low": 0.0, "rotor_speed_high": robot.margins.rotor_speed}
    for name, m in margins.items():
        assert m.design_margin == pytest.approx(design[m.kind], abs=1e-9), name
        assert m.margin_physical == pytest.approx(m.margin_planning + design[m.kind], abs=1e-9), name
    bare = physical_robot(robot)
    assert bare.margins.ground == 0.0 and robot.margins.ground > 0  # the robot itself is untouched
    assert bare.kind.robot is bare and robot.kind.robot is robot


def test_a_log_below_the_ground_breaks_the_physical_limit_at_that_tick(study_plan):
    robot = study_plan.robot
    log = follow(study_plan)
    k, depth = 700, 0.03  # tick, and how far below the ground [m]
    z = log.coordinates.index("z")
    clearance = study_plan.trajectory.evaluate(log.t[k:k + 1], order=0)[0, 0]  # planned s at tick k
    joints = robot.kind.drone_joints(clearance)
    lowest = joints[:, 1].min() - robot.kind.ground_height  # height of the lower drone joint above the ground
    log.q[k, z] -= lowest + depth  # the whole chain moves down: the lower joint is `depth` under the ground
    margins = closed_loop_margins(study_plan, log)
    worst = min((margins["ground_1"], margins["ground_2"]), key=lambda m: m.margin_physical)
    assert worst.margin_physical == pytest.approx(-depth, abs=1e-9)
    assert worst.time_physical == pytest.approx(log.t[k])
    assert worst.margin_planning == pytest.approx(-depth - robot.margins.ground, abs=1e-9)
    assert worst.breaks_physical and worst.state == "BROKEN" and broken(margins)[0] == worst
    message = broken_message(margins)
    assert worst.name in message and f"t = {log.t[k]:.3f} s" in message
    document = simulation_document(log, margins)
    entry = document["constraints"][worst.name]
    assert entry["margin_physical"] < 0 and entry["unit"] == "m" and document["broken_physical"][0] == worst.name
    json.dumps(document)  # JSON-friendly


def test_eating_a_design_margin_is_reported_not_broken(study_plan):
    log = follow(study_plan)
    robot = study_plan.robot
    k, past = 400, 50.0  # a rotor 50 rad/s past the planning limit, 100 rad/s under w_max
    log.speed[k, 0, 2] = robot.rotor_constants.max_speed - robot.margins.rotor_speed + past
    m = closed_loop_margins(study_plan, log)["rotor_speed_high_1"]
    assert m.margin_planning == pytest.approx(-past) and m.time_planning == pytest.approx(log.t[k])
    assert m.margin_physical == pytest.approx(robot.margins.rotor_speed - past) and m.detail == "rotor 3"
    assert m.eats_design_margin and not m.breaks_physical and m.state == "margin eaten"
    series = margin_series(study_plan, log)["rotor_speed_high_1"]
    assert series.planning[k] == pytest.approx(-past) and np.argmin(series.planning) == k


def test_the_thrust_floor_is_read_back_from_the_report():
    from fpr.robots.prototype_singularity import min_thrust

    result = plan(load_mission("cross-singularity"), "none")  # the crossing's first guess, checked with the floor
    assert thrust_floor(result.report) == pytest.approx(min_thrust(result.robot), rel=1e-12)
    assert thrust_floor(plan(load_mission("study"), "none").report) is None


def test_a_log_of_another_robot_is_refused(study_plan):
    log = follow(study_plan)
    log.robot_name = "prototype"
    with pytest.raises(ModelArgumentError, match="simulate this plan"):
        closed_loop_margins(study_plan, log)


def test_the_command_line_exits_1_when_the_simulation_breaks_a_physical_limit(tmp_path, monkeypatch, capsys):
    def sunk(result, settings=None, progress=None, in_flight=None):
        """The drones' joints 5 cm under the ground at t = 1 s."""
        log = follow(result)
        k = int(round(1.0 / TICK))
        log.q[k:k + 5, log.coordinates.index("z")] -= 2.0
        return log

    monkeypatch.setattr(cli, "simulate", sunk)
    out = tmp_path / "run"
    code = cli.main(["--mission", "study", "--method", "none", "--simulate", "--no-plots", "--quiet",
                     "--out", str(out)])
    assert code == contract.LIMIT_BROKEN
    err = capsys.readouterr().err
    assert "broke a physical limit" in err and "ground_" in err and "t = 1.000 s" in err
    document = json.loads((out / "simulation.json").read_text())
    assert document["broken_physical"] and all(document["constraints"][n]["margin_physical"] < 0
                                               for n in document["broken_physical"])
    assert {"ground_1", "ground_2", "q21_low", "roll_1", "rotor_speed_high_2"} <= set(document["constraints"])
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["exit_code"] == 1 and "simulation.json" in manifest["files"]
    # same run, same bytes: no wall-clock entry in simulation.json (the manifest has the timings)
    assert not {"wall_time_s", "real_time_factor"} & set(document["summary"])
    again = tmp_path / "again"
    cli.main(["--mission", "study", "--method", "none", "--simulate", "--no-plots", "--quiet", "--out", str(again)])
    assert (again / "simulation.json").read_bytes() == (out / "simulation.json").read_bytes()
