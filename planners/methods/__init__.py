"""The planning methods, found by name: each is a function ``(mission, robot, options) -> PlanResult``
(:class:`planners.options.PlanningMethod`), one module per method.

Adding a method: write ``planners/methods/<name>.py`` with a ``plan(mission, robot, options)`` that
returns a :class:`~planners.result.PlanResult` (the shared pieces: :mod:`planners.methods.way_points`,
:func:`planners.optimisation.solving.solve_stage`, :func:`planners.optimisation.solving.solve_refining`,
:func:`planners.problem.report.evaluate_motion`), import it below and add one line to :data:`METHODS`.
:func:`planners.optimize.plan`, ``python -m fpr.plan --method`` and the studies read this registry.
"""

from __future__ import annotations

from fpr.model.errors import MissionError, UnknownMethodError
from planners.methods import crossing, none, one_step, two_step
from planners.options import PlanningMethod

#: Name -> planning method.
METHODS: dict[str, PlanningMethod] = {
    "two-step": two_step.plan,
    "one-step": one_step.plan,
    "none": none.plan,
    "crossing": crossing.plan,
}

#: The methods that plan a singularity-crossing mission (``cross_singularity = true``); the others
#: plan way-point missions.
CROSSING_METHODS = ("crossing",)


def method_for(mission, method: str) -> PlanningMethod:
    """The function that plans ``mission`` with the registered ``method``.

    A singularity-crossing mission can only be planned by a crossing method: ``"none"`` gives it its
    first guess (:func:`planners.methods.crossing.first_guess`, its reference as the stop motion is
    the others'), any other method its optimised crossing.

    Raises:
        UnknownMethodError: ``method`` is not in :data:`METHODS`.
        MissionError: a crossing method asked for a mission that does not cross a singularity.
    """
    if method not in METHODS:
        raise UnknownMethodError(method, tuple(METHODS))
    crossing_mission = bool(getattr(mission, "cross_singularity", False))
    if crossing_mission and method not in CROSSING_METHODS:
        return crossing.first_guess if method == "none" else METHODS[CROSSING_METHODS[0]]
    if method in CROSSING_METHODS and not crossing_mission:
        raise MissionError("cross_singularity", f"method {method!r} plans singularity-crossing missions only "
                           "(cross_singularity = true): use "
                           + ", ".join(m for m in METHODS if m not in CROSSING_METHODS), mission.name)
    return METHODS[method]
