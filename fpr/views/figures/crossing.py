"""Crossing the prototype's Type-2 singularity (seed ch. 4, Fig. 4.2-4.9): the approaches side by side."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from fpr.model.errors import FigureError
from fpr.model.inverse_dynamics import MOTION_ORDER, inverse_dynamics
from fpr.sim.margins import thrust_floor
from fpr.views.figures.style import STYLE, _finish, _limit, _new_figure, _png_path, _save_to_file, _styled

if TYPE_CHECKING:
    from matplotlib.figure import Figure

def _crossing_comparison(robot, outcomes: Sequence, rate: float) -> Figure:
    """The figure of :func:`crossing_comparison_figure`, not written."""
    if not outcomes:
        raise FigureError("outcomes", outcomes, "outcomes is empty: give at least one "
                                                "planners.crossing.solve.CrossingOutcome")
    colors = [STYLE["plan_color"], "tab:orange", "tab:green", "tab:purple"]
    limit = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    max_thrust = 4 * robot.rotor_constants.thrust_coefficient * limit**2
    with _styled():
        fig, axes = _new_figure(3, 1, height=7.5, sharex=False)
        for k, out in enumerate(outcomes):
            trajectory = out.trajectory
            t = trajectory.sample_times(rate)
            m = trajectory.evaluate(t, order=MOTION_ORDER)
            inputs = inverse_dynamics(robot, m)
            tau = t - out.crossing_time  # time from the crossing
            color = colors[k % len(colors)]
            label = out.name + ("" if out.feasible else " (limits violated)")
            axes[0].plot(tau, m[0][:, 1], color=color, label=label)
            axes[1].plot(tau, inputs.thrust[:, 0], color=color, label=label)
            w = inputs.rotor_speed[:, 0]
            axes[2].plot(tau, w.max(axis=-1), color=color, label=label)
            axes[2].plot(tau, w.min(axis=-1), color=color, linestyle="--", linewidth=STYLE["thin_width"])
        axes[0].axhline(0.0, color=STYLE["reference_color"], linewidth=STYLE["thin_width"], zorder=1)
        axes[0].set_ylabel(r"$q_2$ [rad]")
        _limit(axes[1], max_thrust)
        floors = [f for f in (thrust_floor(out.report) for out in outcomes if hasattr(out, "report")) if f is not None]
        if floors:  # the least thrust the crossings are planned with (the controller steers the thrust's direction)
            axes[1].axhline(floors[0], color=STYLE["limit_color"], linestyle="-.", linewidth=STYLE["thin_width"],
                            label=f"thrust floor {floors[0]:.2f} N", gid="thrust floor", zorder=1)
        axes[1].set_ylabel(r"thrust $|F|$ [N]")
        _limit(axes[2], limit)
        _limit(axes[2], 0.0)
        axes[2].set_ylabel(r"rotor speeds, max / min [rad/s]")
        for ax in axes[1:]:
            low, high = ax.get_ylim()  # the seed's approaches reach 1e3..1e6: keep the limits readable
            span = 4 * (limit if ax is axes[2] else max_thrust)
            ax.set_ylim(0.0 if ax is axes[1] else max(low, -span), min(high, span))
        for ax in axes:
            ax.axvline(0.0, color=STYLE["reference_color"], linestyle=STYLE["reference_style"],
                       linewidth=STYLE["thin_width"], zorder=1)
            ax.set_xlabel("time from the crossing [s]")
        return _finish(fig, "Fig. 4.2-4.9 — crossing the prototype's Type-2 singularity", axes[:2])


def crossing_comparison_figure(path: str | Path, robot, outcomes: Sequence, rate: float = 500.0) -> Path:
    """Write the crossing approaches side by side (seed Fig. 4.2-4.9): q2, the thrust and the extreme
    rotor speeds against time from the crossing, with the thrust limit 4 c_T (w_max - m_gr)^2 and the
    rotor limits [0, w_max - m_gr] (the vertical axes are clipped at 4x the limit).

    Args:
        path: the PNG file to write.
        robot: the prototype.
        outcomes: :class:`planners.crossing.solve.CrossingOutcome` s (the seed's approaches, ours).
        rate: sampling rate [Hz].

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        FigureError: no outcome, or a suffix other than .png.
    """
    target = _png_path(path)
    return _save_to_file(_crossing_comparison(robot, outcomes, rate), target)
