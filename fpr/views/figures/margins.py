"""Closed-loop margins against both limits: :func:`margins_figure` (:mod:`fpr.sim.margins`).

One panel per planned constraint, the closed loop's margin to the **planning limit** over time (solid), with
the planning limit at 0 (red dotted: below it the closed loop eats into the design margin m_gd, m_ga, m_gr or
the thrust floor) and the **physical limit** (black solid, at minus the design margin: below it the robot
breaks a physical limit). The plan's own worst margin is a grey dashed line.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fpr.model.errors import FigureError
from fpr.views.figures.style import (
    LIMIT_LABEL,
    STYLE,
    _finish,
    _new_figure,
    _png_path,
    _save_to_file,
    _styled,
)

#: Legend labels of the limit lines (the planning limit's gid is :data:`LIMIT_LABEL`, the physical one's its label).
PLANNING_LABEL = "planning limit (design margins kept)"
PHYSICAL_LABEL = "physical limit"


def margins_figure(path: str | Path, series: dict, title: str = "Closed-loop margins of the planned constraints",
                   names=None) -> Path:
    """Draw the closed-loop margins of :func:`fpr.sim.margins.margin_series` and write them as a PNG file.

    Args:
        path: the PNG file to write.
        series: constraint name -> :class:`fpr.sim.margins.MarginSeries`.
        title: the figure's title.
        names: the constraints to draw, in order (default: all of ``series``).

    Returns:
        ``path``.

    Raises:
        FigureError: no constraint to draw, an unknown name, or a path that is not a PNG file.
    """
    out = _png_path(path)
    names = list(series) if names is None else list(names)
    unknown = [n for n in names if n not in series]
    if not names or unknown:
        raise FigureError("names", unknown or names, f"draw at least one of {', '.join(series)}")
    cols = 2 if len(names) > 3 else 1
    rows = math.ceil(len(names) / cols)
    with _styled():
        fig, axes = _new_figure(rows, cols, width=STYLE["width"] * (1.5 if cols == 2 else 1.0),
                                height=0.9 + 1.6 * rows)
        for ax, name in zip(axes, names, strict=False):
            s = series[name]
            design = s.physical - s.planning  # the design margin at each tick (constant for most kinds)
            ax.plot(s.t, s.planning, color=STYLE["plan_color"], linewidth=STYLE["thin_width"] * 1.5,
                    label="closed loop", gid="closed loop", zorder=3)
            ax.axhline(0.0, color=STYLE["limit_color"], linestyle=STYLE["limit_style"],
                       linewidth=STYLE["limit_width"], label=PLANNING_LABEL, gid=LIMIT_LABEL, zorder=2)
            ax.plot(s.t, -design, color="black", linestyle="-.", linewidth=STYLE["thin_width"],
                    label=PHYSICAL_LABEL, gid=PHYSICAL_LABEL, zorder=1)
            ax.axhline(s.planned, color=STYLE["reference_color"], linestyle=STYLE["reference_style"],
                       linewidth=STYLE["thin_width"], label="planned worst", gid="planned", zorder=1)
            k = int(np.argmin(s.planning))
            ax.plot(s.t[k], s.planning[k], marker="v", color=STYLE["plan_color"], linestyle="none", zorder=4)
            ax.set_title(f"{name}: worst {s.planning[k]:+.3g} {s.unit} at t = {s.t[k]:.2f} s", fontsize=8)
            ax.set_ylabel(f"margin [{s.unit}]")
            top = max(float(s.planning.max()), s.planned, 0.0)
            bottom = min(float(-design.max()), float(s.planning.min()))
            pad = 0.1 * (top - bottom) or 1.0
            ax.set_ylim(bottom - pad, top + pad)
        for ax in axes[len(names):]:
            ax.set_visible(False)
        for ax in axes[-cols:]:
            ax.set_xlabel("t [s]")
        handles, labels = axes[0].get_legend_handles_labels()
        fig = _finish(fig, title, [])  # one legend for all panels, above them
        fig.subplots_adjust(top=1.0 - 1.0 / fig.get_figheight())
        fig.legend(handles, labels, loc="upper center", ncol=4, fontsize=STYLE["legend_size"],
                   bbox_to_anchor=(0.5, 1.0 - 0.45 / fig.get_figheight()))
    return _save_to_file(fig, out)
