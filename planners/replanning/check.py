"""The replanner's last evaluation and its dense check in one inverse-dynamics call.

A replan ends with the value of J and the constraints at the final point on the optimisation grid (the SQP's
last ratio test) and the check of that motion on the dense grid (:func:`planners.problem.disturbance.dense_check`).
Both are the inverse dynamics (:func:`fpr.model.inverse_dynamics.inverse_dynamics`) of the same motion at
two sets of samples, and on the replanner's sizes (14-28 grid nodes, 70-500 dense samples) a call costs
mostly its fixed overhead (28 samples cost about a third of 600; ``python -m fpr.bench --section replan``
prints the phases): :func:`evaluate_and_check` makes one call of
the grid nodes and the dense samples together and splits the result, so that the final evaluation is the
problem's own (:meth:`planners.problem.motion.MotionProblem.evaluate`, values only) and the check is
:func:`~planners.problem.disturbance.dense_check`'s (same samples, rows, tolerances and verdict).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fpr.model.inverse_dynamics import MotionInputs, inverse_dynamics
from fpr.model.jets import Jet
from planners.problem.disturbance import dense_times, generalized_gust, verdict
from planners.trajectory.polynomial import PiecewisePolynomial


def _split(inputs: MotionInputs, n: int) -> tuple[MotionInputs, MotionInputs]:
    """The first n samples of ``inputs`` and the rest (``motion`` holds the samples on its axis 1)."""
    head, tail = {}, {}
    for f in dataclasses.fields(inputs):
        value = getattr(inputs, f.name)
        axis = 1 if f.name == "motion" else 0
        head[f.name], tail[f.name] = np.split(value, [n], axis=axis)
    return MotionInputs(**head), MotionInputs(**tail)


def evaluate_and_check(problem, x, rate: float, start_time: float = 0.0, gusts=()):
    """``problem.evaluate(x)`` (values only) and the dense check of its motion from one inverse-dynamics call.

    Args:
        problem: the replan's NLP (:class:`planners.problem.motion.MotionProblem`, or
            :class:`planners.problem.disturbance.DisturbedProblem` with its Q_ext at the grid nodes).
        x: the point (n_x,).
        rate: rate of the dense check [Hz] (plus the part's knots).
        start_time: absolute time of the problem's first point [s] (when the ``gusts`` push).
        gusts: the gust events the dense check flies the motion in.

    Returns:
        (the :class:`planners.problem.motion.Evaluation` at x, (feasible, violated names worst first, samples)).
    """
    x = np.asarray(x, dtype=float)
    points = problem.points_of(x)
    part = PiecewisePolynomial(points, problem.durations)
    t = dense_times(part, rate)
    dense = part.evaluate(t, order=4)
    grid = problem.motion(points)
    n = grid.shape[1]
    on_grid = getattr(problem, "external", None)
    on_dense = generalized_gust(problem.robot, gusts, start_time + t, dense[0]) if gusts else None
    external = None
    if on_grid is not None or on_dense is not None:
        external = Jet(np.concatenate([
            on_grid if on_grid is not None else np.zeros((3,) + grid.shape[1:]),
            on_dense if on_dense is not None else np.zeros((3,) + dense.shape[1:]),
        ], axis=1))
    inputs = inverse_dynamics(problem.robot, np.concatenate([grid, dense], axis=1), external=external)
    grid_inputs, dense_inputs = _split(inputs, n)
    # the problem's own value path (windows, back-off, objective) on these inputs: its inverse-dynamics
    # hook answers with them for this one evaluation (the motion it asks for is ``grid``)
    own = problem.__dict__.get("_inputs")  # a hook the caller set on this instance (an instrument) stays
    problem._inputs = lambda motion: grid_inputs
    try:
        evaluation = problem.evaluate(x)
    finally:
        if own is None:
            del problem._inputs
        else:
            problem._inputs = own
    feasible, violated = verdict(problem.robot, dense, dense_inputs)
    return evaluation, (feasible, violated, int(t.size))


__all__ = ["evaluate_and_check"]
