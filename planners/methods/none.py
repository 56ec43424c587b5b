"""Method ``"none"``: stop at every way point (s' = s'' = s''' = s'''' = 0 there), no optimisation.

The reference motion that normalises the objective (3.26): its J is 1 by definition.
"""

from __future__ import annotations

import numpy as np

from planners.methods.way_points import WayPointTask
from planners.options import PlanOptions
from planners.problem.report import evaluate_motion
from planners.result import PlanResult


def plan(mission, robot, options: PlanOptions) -> PlanResult:
    """The stop-at-every-way-point motion of ``mission``, checked at ``options.dense_rate``."""
    task = WayPointTask.of(mission, robot)
    reference = evaluate_motion(robot, task.stop, options.dense_rate)
    return task.result("none", task.stop, np.ones(len(task.stop.points), dtype=bool), reference, reference, [])
