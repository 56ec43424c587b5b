"""The benchmark's goal rows: the allocation replay's split by route, and the goals' verdicts."""

from __future__ import annotations

import numpy as np

import fpr
from controllers.allocation import Allocator
from fpr.cli.bench.cli import _goals
from fpr.cli.bench.loop_allocation import replay, replay_paths
from fpr.cli.bench.model import MASS_MATRIX_GOAL_S, model_targets
from fpr.cli.bench.timing import Bench
from fpr.sim.plant import hover_configuration, hover_speeds


def _calls(robot, rng, factors):
    """(attitude, thrust, u_a) near hover, the thrust scaled by each factor (3: rotors saturate)."""
    q0 = hover_configuration(robot, robot.kind.reference_chain)
    speeds = hover_speeds(robot, q0)
    hover = np.array([rotor.wrench(w**2)[0] for rotor, w in zip(robot.rotors, speeds, strict=True)])
    n_a = len(robot.layout.attitude)
    return [(robot.attitude_model(q0 + 0.01 * rng.normal(size=robot.nq), np.zeros(robot.nq)), f * hover,
             0.01 * rng.normal(size=n_a)) for f in factors]


def test_replay_splits_the_ticks_by_route():
    """6 ticks at hover thrust (closed form), then 4 at 3 times hover (a bound active): counted as such."""
    robot = fpr.load("fpr")
    calls = _calls(robot, np.random.default_rng(0), [1.0] * 6 + [3.0] * 4)
    out = replay(robot, calls, passes=2)
    assert out["ticks"] == 10 and out["bound_active_ticks"] == 4
    assert out["closed_form"]["ticks"] == 6 and out["qp"]["ticks"] == 4 and out["all"]["ticks"] == 10
    for route in ("all", "closed_form", "qp"):
        s = out[route]
        assert 0.0 < s["median_s"] <= s["p90_s"] <= s["max_s"]


def test_replay_says_which_path_it_measured():
    """The Python path by request; both paths interleaved: one dict each, the same ticks split alike (the native
    path only where the extension is built).
    """
    robot = fpr.load("prototype")
    calls = _calls(robot, np.random.default_rng(1), [1.0] * 3 + [3.0] * 3)
    assert replay(robot, calls, passes=1, compiled=False)["path"] == "Python"
    default, python = replay_paths(robot, calls, 2, (None, False))
    assert python["path"] == "Python"
    assert default["path"] == ("native (C)" if Allocator(robot).compiled else "Python")
    assert default["bound_active_ticks"] == python["bound_active_ticks"] == 3


def test_goals_carry_value_goal_and_verdict():
    bench = Bench(1, 0.001, False)
    bench.results.append(dict(name="fpr r.mass_matrix", median_s=2 * MASS_MATRIX_GOAL_S))
    control = dict(targets=[dict(target="RTF >= 20", value=25.0, goal=20.0, unit="x", met=True)])
    planning = dict(targets=[dict(target="two-step < 2 s", value=3.0, met=False)])
    goals = _goals(bench, planning, control)
    assert [g["section"] for g in goals] == ["model", "planning", "control"]
    assert [g["verdict"] for g in goals] == ["not met", "not met", "met"]
    assert goals[0]["goal"] == MASS_MATRIX_GOAL_S and goals[0]["value"] == 2 * MASS_MATRIX_GOAL_S
    assert model_targets([]) == []
