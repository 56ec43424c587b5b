"""Figures of the thesis' planning and simulation chapters (seed 3.2.5-3.3.2) and of its ch. 4, as PNG files.

One module per family of figures:

============================================ ========================================================
:mod:`~fpr.views.figures.planning`           a planned motion: Fig. 3.11-3.18 (FPR), 3.36-3.41 (prototype)
:mod:`~fpr.views.figures.simulation`         a simulation against its plan: Fig. 3.19-3.32, 3.42-3.51
:mod:`~fpr.views.figures.studies`            the parameter studies: Fig. 3.7-3.10
:mod:`~fpr.views.figures.crossing`           crossing the prototype's singularity: Fig. 4.2-4.9
:mod:`~fpr.views.figures.margins`            closed-loop margins of the planned constraints, both limits
:mod:`~fpr.views.figures.chain`              the chain at a few instants (stroboscopic) and as a GIF / MP4
:mod:`~fpr.views.figures.all_figures`        :func:`figure_set`, every figure of a motion at once
:mod:`~fpr.views.figures.style`              :data:`STYLE`, styling context, saving, limit lines, markers
:mod:`~fpr.views.figures.sampled`            checks of a sampled plan, :func:`cumulative_integral`
:mod:`~fpr.views.figures.robot_info`         what the figures ask of ``robot.kind``: titles, points, bounds
============================================ ========================================================

Entry points (all importable from here):

* :func:`figure_set` writes every figure that applies to a planned motion (a
  :class:`planners.optimize.PlanResult` or a sampled plan), optionally against the
  stop-at-every-way-point reference and with a closed-loop :class:`fpr.sim.closed_loop.SimulationLog`,
  for the FPR (Fig. 3.11-3.32) or the prototype (Fig. 3.36-3.51). It calls the next two.
* :func:`plan_figures` draws one planned motion (and optionally the reference it is compared
  with) in the figures of seed 3.11-3.18 (FPR) or 3.36-3.41 (prototype), plus the rotor speeds
  and rotor forces against the limits of eq. 3.48 (:data:`PLAN_FIGURES`).
* :func:`simulation_figures` draws a simulation log against its plan (seed 3.19-3.32, 3.42-3.51;
  :data:`SIMULATION_FIGURES`).
* :func:`via_point_study_figure` and :func:`alpha_study_figure` draw the parameter studies of
  seed 3.2.5 (Fig. 3.7-3.10); :func:`crossing_comparison_figure` the approaches of seed ch. 4.
* :func:`margins_figure` draws :func:`fpr.sim.margins.margin_series` (every planned constraint in closed loop
  against the planning and the physical limit).

Every ``_<name>_figure`` / ``_sim_<name>`` builder returns a :class:`matplotlib.figure.Figure`
without writing it, so that tests (and users) can inspect the axes.

A *sampled plan* is a :class:`planners.optimize.SampledPlan` (``PlanResult.sampled(rate)``) or any
object with the attributes

=========== ===================== =================================================================
``label``   str                   legend text, e.g. "optimised (two-step)"
``t``       (N,) [s]              sample times, non-decreasing
``motion``  (5, N, n_s)           s and its derivatives 0..4 (FPR s = [y z phi q21],
                                  prototype xi = [q1 q2])
``inputs``  MotionInputs          :class:`fpr.model.inverse_dynamics.MotionInputs` at the N samples
``knots``   (m+1,) [s]            times of all points of the piecewise polynomial
``is_way``  (m+1,) bool           True for a way point, False for a via point
``points``  (m+1, 5, n_s)         the points; ``points[:, 0]`` are positions in planning coordinates
=========== ===================== =================================================================

One style everywhere (:data:`STYLE`): the plan is drawn solid in one colour, the reference dashed
grey, limits as red dotted lines labelled "limit", way points as filled markers and via points as
open ones. In the simulation figures the simulated motion is solid and the plan dashed grey.
Every axis label carries its unit.

matplotlib is imported lazily, inside the functions, and only through
:class:`matplotlib.figure.Figure` with an Agg canvas: pyplot is never imported, so the caller's
backend, open figures and rcParams are left alone (the style is applied in an
:func:`matplotlib.rc_context`).

Wrong inputs raise :class:`fpr.model.errors.FigureError` or :class:`fpr.model.errors.ShapeError`
(both :class:`fpr.model.errors.FprError` and ``ValueError``) before anything is written.
"""

from fpr.views.figures.all_figures import FIGURE_SET, figure_set
from fpr.views.figures.crossing import _crossing_comparison, crossing_comparison_figure  # noqa: F401
from fpr.views.figures.margins import margins_figure
from fpr.views.figures.planning import PLAN_FIGURES, plan_figures
from fpr.views.figures.sampled import cumulative_integral
from fpr.views.figures.simulation import SIMULATION_FIGURES, simulated_indices, simulation_figures
from fpr.views.figures.studies import alpha_study_figure, via_point_study_figure
from fpr.views.figures.style import LIMIT_LABEL, STYLE
from planners.optimize import SampledPlan

__all__ = [
    "FIGURE_SET",
    "LIMIT_LABEL",
    "PLAN_FIGURES",
    "SIMULATION_FIGURES",
    "STYLE",
    "SampledPlan",
    "alpha_study_figure",
    "crossing_comparison_figure",
    "cumulative_integral",
    "figure_set",
    "margins_figure",
    "plan_figures",
    "simulated_indices",
    "simulation_figures",
    "via_point_study_figure",
]
# _crossing_comparison: tests/test_crossing.py imports it from here (it could import it from .crossing)
