"""Replan live from sliders in a notebook: :class:`LivePlan` (notebooks 02 and 03).

A :class:`LivePlan` holds a mission and replans it with new via points per travel, weight alpha and travel
time (:meth:`LivePlan.replan`), keeping the last result and one line per plan in ``history``;
:meth:`LivePlan.widget` wraps it in ipywidgets sliders (``ipywidgets.interactive``, updated when a slider is
released). ipywidgets is optional (the ``notebooks`` extra): it is imported only by :meth:`LivePlan.widget`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fpr import extras
from planners.optimize import plan


@dataclass
class LivePlan:
    """A mission replanned on demand.

    Attributes:
        mission: the :class:`planners.missions.mission.Mission` to replan.
        method: the planning method (``"two-step"``...).
        robot: its robot (default ``mission.load_robot()``).
        rate: sampling rate of the drawn path [Hz].
        result: the last :class:`planners.result.PlanResult` (None before the first plan).
        history: one dict per plan: the settings, J, J_e, J_phi, feasible, wall time.
    """

    mission: object
    method: str = "two-step"
    robot: object = None
    rate: float = 50.0
    result: object = None
    history: list = field(default_factory=list)

    def __post_init__(self):
        self.robot = self.robot or self.mission.load_robot()

    def replan(self, via_points: int, alpha: float, time: float, draw: bool = True):
        """Plan the mission with ``via_points`` per travel, weight ``alpha`` and every travel ``time`` [s] long.

        Prints one line (J, J_e, J_phi, peak rotor speed, feasible, planning time) and, with ``draw``, the
        task-space path against the stop-at-way-points one. Returns the :class:`PlanResult`.
        """
        mission = self.mission.replace(via_points=int(via_points), alpha=float(alpha),
                                       times=np.full(len(self.mission.times), float(time)))
        result = plan(mission, self.method, robot=self.robot)
        peaks = result.report.peaks(self.robot)
        row = {"via_points": int(via_points), "alpha": float(alpha), "time_s": float(time), "J": result.J,
               "J_e": result.report.J_e, "J_phi": result.report.J_phi, "feasible": result.feasible,
               "peak_rotor_speed": peaks["peak_rotor_speed_rad_s"], "wall_time_s": result.wall_time}
        self.result = result
        self.history.append(row)
        print(f"n_vp = {row['via_points']}, alpha = {row['alpha']:.2f}, T = {row['time_s']:.2f} s per travel: "
              f"J = {row['J']:.4f}, J_e = {row['J_e']:.2f} J, J_phi = {row['J_phi']:.4f} rad^2/s, "
              f"peak rotor speed {row['peak_rotor_speed']:.0f} rad/s, "
              f"{'feasible' if row['feasible'] else 'NOT feasible'} ({row['wall_time_s']:.2f} s to plan)")
        if draw:
            self._draw(result)
        return result

    def _draw(self, result) -> None:
        """The task-space path of ``result`` (solid) and of stopping at every way point (dashed), inline."""
        import matplotlib.pyplot as plt  # pyplot only here: inline display in a notebook

        fig, ax = plt.subplots(figsize=(5.0, 3.6))
        for motion, style, label in ((result.report.motion[0], "-", "optimised"),
                                     (result.reference.motion[0], "--", "stop at way points")):
            main, _ = self.robot.kind.task_points(motion)
            ax.plot(main[:, 0], main[:, 1], style, label=label)
        points, _ = self.robot.kind.task_points(np.asarray(result.trajectory.points)[:, 0])
        ax.plot(points[result.is_way, 0], points[result.is_way, 1], "o", color="tab:blue", label="way point")
        ax.plot(points[~result.is_way, 0], points[~result.is_way, 1], "o", mfc="none", color="tab:blue",
                label="via point")
        ax.set_xlabel("y [m]")
        ax.set_ylabel("z [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
        ax.set_title(f"{self.robot.kind.task_point_labels[0]} path, J = {result.J:.4f}")
        fig.tight_layout()
        plt.show()

    def widget(self, via_points=(0, 4), alpha=(0.0, 1.0, 0.1), time=(1.5, 6.0, 0.5)):
        """ipywidgets sliders for n_vp, alpha and the travel time that call :meth:`replan` when released.

        Args:
            via_points: (min, max) via points per travel.
            alpha: (min, max, step) of the weight.
            time: (min, max, step) of every travel's duration [s].

        Returns:
            the ``ipywidgets.interactive`` (its ``children[:3]`` are the sliders; setting a slider's
            ``value`` replans).
        """
        extras.require("notebooks", ("ipywidgets",))
        import ipywidgets as widgets  # optional: the notebooks extra

        start = self.mission
        sliders = dict(
            via_points=widgets.IntSlider(value=int(start.via_points[0]), min=via_points[0], max=via_points[1],
                                         description="n_vp", continuous_update=False),
            alpha=widgets.FloatSlider(value=float(start.alpha), min=alpha[0], max=alpha[1], step=alpha[2],
                                      description="alpha", continuous_update=False),
            time=widgets.FloatSlider(value=float(start.times[0]), min=time[0], max=time[1], step=time[2],
                                     description="T [s]", continuous_update=False),
        )
        return widgets.interactive(self.replan, **sliders)
