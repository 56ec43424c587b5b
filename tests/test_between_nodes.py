"""What happens between the optimisation grid's nodes: the dynamic rows' parabola vertices
(planners.problem.motion.between_node_minima) with their exact derivatives, and the two-step method's
refinement of a plan that fails the dense check by its polish alone.
"""

from __future__ import annotations

import numpy as np
import pytest

from fpr.bench.missions import MissionFamily
from planners.methods.one_step import one_step_problem
from planners.methods.way_points import WayPointTask
from planners.optimisation.solving import Grid
from planners.optimize import plan
from planners.problem.motion import between_node_minima


def test_a_quadratic_dip_between_nodes_is_found_exactly():
    """A row that is a parabola of time with its vertex between two nodes: the node that owns the vertex takes
    the vertex's value and offset; rows that do not dip, and the skipped columns, are left as they are.
    """
    k = 9
    t = np.arange(k, dtype=float)
    dip = 0.3 * (t - 3.4) ** 2 - 0.1  # vertex at 3.4 spacings: node 3 owns it (tau = 0.4)
    straight = 2.0 - 0.1 * t  # no dip
    cap = -(t - 4.0) ** 2  # curves downwards: its minima are at the nodes
    rows = np.stack([dip, straight, cap, dip], axis=1)
    out, tau = between_node_minima(rows, k, skip=1)  # the first column left as it is
    assert out[3, 3] == pytest.approx(-0.1, abs=1e-14) and tau[3, 3] == pytest.approx(0.4, abs=1e-14)
    assert np.array_equal(np.flatnonzero(tau[:, 3]), [3]) and out[:, 3].min() == pytest.approx(-0.1)
    np.testing.assert_array_equal(out[:, :3], rows[:, :3])  # skipped; no dip; curving down
    # the vertex of a dip between a segment's first two nodes: the second node covers it (tau in [-1, -1/2))
    early = 0.5 * (t - 0.3) ** 2
    out, tau = between_node_minima(early[:, None], k)
    assert out[1, 0] == pytest.approx(0.0, abs=1e-14) and tau[1, 0] == pytest.approx(-0.7)


def test_rows_between_nodes_have_exact_derivatives():
    """The constraints' Jacobian (the Lagrange weights at each vertex times its nodes' derivatives) against
    central finite differences, on a fast random mission where rows dip between nodes.
    """
    mission = MissionFamily("prototype", 4, via_points=(1, 1), time_range=(1.1, 1.1)).mission(1)
    problem = one_step_problem(WayPointTask.of(mission, mission.load_robot()), Grid())
    rng = np.random.default_rng(0)
    x = problem.x_of(problem.points) + 0.01 * rng.standard_normal(problem.n_x)
    ev = problem.evaluate(x, True)
    _, rows, _, _ = problem._node_derivatives(problem.points_of(x), problem.motion(problem.points_of(x)))
    assert np.count_nonzero(between_node_minima(rows, problem.samples_per_segment,
                                                problem._half_step_columns)[1]) > 0  # some rows do dip
    jac = ev.jacobian
    h = 1e-6
    for k in rng.choice(problem.n_x, 6, replace=False):
        e = np.zeros(problem.n_x)
        e[k] = h
        fd = (problem.evaluate(x + e).constraints - problem.evaluate(x - e).constraints) / (2 * h)
        # the windows' minima may switch node within +-h: compare where the same node is picked both ways
        same = np.abs(fd - jac[:, k]) <= 1e-5 * (1.0 + np.abs(jac[:, k]))
        assert same.mean() > 0.99, k


def test_a_two_step_plan_that_fails_the_dense_check_is_refined_by_its_polish():
    """A random prototype mission whose rotor speeds peak between the nodes: the refined attempt is the polish
    alone on the grid twice as fine (not both steps again), and the plan holds on the 500 Hz grid.
    """
    mission = MissionFamily("prototype", 32, space="joint", arm="down").mission(1)
    result = plan(mission, "two-step")
    refined = [st.name for st in result.stages if "refined" in st.name]
    assert refined == ["polish (one-step) (grid refined x2)"]
    assert result.feasible
