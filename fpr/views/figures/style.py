"""The figures' shared style and drawing helpers: :data:`STYLE`, the styling context, new figures on an Agg
canvas, finishing (title, legends, layout) and saving a figure, limit lines, way / via point markers.

matplotlib is imported lazily, inside the functions, and only through :class:`matplotlib.figure.Figure`
with an Agg canvas: pyplot is never imported, so the caller's backend, open figures and rcParams are
left alone (the style is applied in an :func:`matplotlib.rc_context`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from contextlib import contextmanager
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from fpr.model.errors import FigureError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

logger = logging.getLogger(__name__)

#: The figures' style: sizes [pt], line widths [pt], colours (matplotlib colour specs), dpi.
STYLE = MappingProxyType({
    "font_size": 9.0,
    "title_size": 10.0,
    "legend_size": 7.0,
    "line_width": 1.6,
    "thin_width": 0.8,
    "marker_size": 5.0,
    "plan_color": "tab:blue",
    "reference_color": "0.45",
    "reference_style": "--",
    "reference_alpha": 0.6,  # the reference's per-rotor curves, drawn in the rotors' colours
    "limit_color": "tab:red",
    "limit_style": ":",
    "limit_width": 1.3,
    "ground_color": "saddlebrown",
    "knot_color": "0.6",
    "knot_alpha": 0.5,
    "drone_colors": ("tab:green", "tab:purple", "tab:orange"),
    "rotor_colors": ("tab:blue", "tab:orange", "tab:green", "tab:purple"),
    "width": 6.4,  # figure width [inch]
    "row_height": 2.1,  # height of one row of subplots [inch]
    "dpi": 120,
})

#: Line styles of rotors 1-4 (with their colours), so that rotors with equal speeds stay visible.
ROTOR_STYLES = ("-", "--", "-.", ":")

#: Legend label of every limit line (also its matplotlib gid, so that tests and users can find them).
LIMIT_LABEL = "limit"


def _rc() -> dict[str, Any]:
    """The rcParams of :data:`STYLE`."""
    return {
        "font.size": STYLE["font_size"],
        "axes.titlesize": STYLE["font_size"],
        "axes.labelsize": STYLE["font_size"],
        "figure.titlesize": STYLE["title_size"],
        "legend.fontsize": STYLE["legend_size"],
        "xtick.labelsize": STYLE["font_size"] - 1,
        "ytick.labelsize": STYLE["font_size"] - 1,
        "lines.linewidth": STYLE["line_width"],
        "lines.markersize": STYLE["marker_size"],
        "axes.grid": True,
        "grid.alpha": 0.3,
        "legend.framealpha": 0.8,
    }


@contextmanager
def _styled():
    """Apply the figures' rcParams for the duration of the block only."""
    import matplotlib

    with matplotlib.rc_context(_rc()):
        yield


def _new_figure(rows: int, cols: int = 1, height: float | None = None, width: float | None = None,
                sharex: bool = True) -> tuple[Figure, np.ndarray]:
    """A Figure on an Agg canvas (no pyplot) and its axes as a (rows * cols,) array."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    size = (width or STYLE["width"], height or (0.6 + STYLE["row_height"] * rows))
    fig = Figure(figsize=size, dpi=STYLE["dpi"])
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, sharex=sharex, squeeze=False)
    return fig, axes.reshape(-1)


def _finish(fig: Figure, title: str, axes: Sequence[Axes], legend_below: bool = False) -> Figure:
    """Title the figure, put a legend in every axes that has labelled artists, lay it out.

    Args:
        fig: the figure.
        title: its title, naming the thesis figure.
        axes: the axes that get a legend (one entry per distinct label).
        legend_below: put the legends under their axes instead of inside them.
    """
    fig.suptitle(title, wrap=True)  # a long title (a crossing's) wraps inside the canvas
    for ax in axes:
        handles, labels = ax.get_legend_handles_labels()
        if not handles:
            continue
        unique = dict(zip(labels, handles, strict=True))
        ncol = 1 if len(unique) <= 4 else 2
        if legend_below:
            ax.legend(unique.values(), unique.keys(), loc="upper center", bbox_to_anchor=(0.5, -0.12),
                      ncol=ncol)
        else:  # beside the axes: never over the data or the limit lines
            ax.legend(unique.values(), unique.keys(), loc="upper left", bbox_to_anchor=(1.01, 1.0), ncol=1,
                      borderaxespad=0.0)
    # laid out again at every draw (savefig's included, inside the style): the tick labels, which the axes' sizes
    # choose, are then the ones drawn; laid out once here only, a y label could end up off the canvas
    fig.set_layout_engine("tight")
    fig.get_layout_engine().execute(fig)
    return fig


def _save(fig: Figure, path: Path) -> Path:
    """Write ``fig`` as a PNG file at the style's dpi, then free its artists; returns ``path``."""
    with _styled():
        fig.savefig(path, dpi=STYLE["dpi"], format="png")
    fig.clear()
    logger.debug("wrote %s", path)
    return path


def _limit(ax: Axes, value: float, vertical: bool = False) -> None:
    """A red dotted limit line (horizontal at y = value, or vertical at x = value), labelled "limit"."""
    kw = {"color": STYLE["limit_color"], "linestyle": STYLE["limit_style"], "linewidth": STYLE["limit_width"],
          "label": LIMIT_LABEL, "gid": LIMIT_LABEL, "zorder": 1}
    (ax.axvline if vertical else ax.axhline)(value, **kw)


def _point_markers(ax: Axes, x: np.ndarray, y: np.ndarray, is_way: np.ndarray, label: bool = True) -> None:
    """Way points as filled markers, via points as open ones, in the plan's colour."""
    color = STYLE["plan_color"]
    if np.any(is_way):
        ax.plot(x[is_way], y[is_way], linestyle="none", marker="o", color=color, gid="way",
                label="way point" if label else None, zorder=4)
    if np.any(~is_way):
        ax.plot(x[~is_way], y[~is_way], linestyle="none", marker="o", markerfacecolor="none",
                markeredgecolor=color, gid="via", label="via point" if label else None, zorder=4)


def _png_path(path: str | Path) -> Path:
    """``path`` as a Path, checked to name a PNG file (FigureError otherwise)."""
    p = Path(path)
    if p.suffix.lower() != ".png":
        raise FigureError("path", path, f"path={str(path)!r}: the figures are PNG files, give a name ending "
                                        "in '.png'")
    return p


def _save_to_file(fig: Figure, path: Path) -> Path:
    """:func:`_save` ``fig`` to ``path``, creating its folder if needed."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return _save(fig, path)


