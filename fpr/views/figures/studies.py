"""The parameter studies of seed 3.2.5 (Fig. 3.7-3.10): the indices against the number of via points and
against the weight alpha of the objective (3.26).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fpr.model.errors import FigureError, ShapeError
from fpr.views.figures.style import STYLE, _finish, _new_figure, _png_path, _save_to_file, _styled

if TYPE_CHECKING:
    from matplotlib.figure import Figure

def _study_arrays(x_name: str, x, energy_ratio, perturbation_ratio) -> tuple[np.ndarray, ...]:
    """The three inputs of a study as float arrays, checked: 1-D, non-empty, finite, of equal lengths."""
    arrays = [np.asarray(a, dtype=float) for a in (x, energy_ratio, perturbation_ratio)]
    names = (x_name, "energy_ratio", "perturbation_ratio")
    for name, a in zip(names, arrays, strict=True):
        if a.ndim != 1 or a.size == 0:
            raise ShapeError(name, a.shape, "(k,) with k >= 1: one value per case of the study")
        if not np.all(np.isfinite(a)):
            raise FigureError(name, a, f"{name} contains NaN or inf: give finite values")
    sizes = {name: a.size for name, a in zip(names, arrays, strict=True)}
    if len(set(sizes.values())) != 1:
        raise FigureError(", ".join(names), sizes, f"mismatched lengths {sizes}: give one energy and one "
                                                   f"perturbation ratio per value of {x_name}")
    return tuple(arrays)


def _value_labels(values) -> list[str]:
    """Bar labels with enough decimals to tell the bars apart and from 1 (0.9996 is not "1"): at least 3
    significant digits, and as many decimals as the smallest difference between two values or from 1 needs.
    """
    v = np.asarray(values, dtype=float)
    gaps = np.abs(np.diff(np.sort(np.append(v, 1.0))))
    gaps = gaps[gaps > 0]
    decimals = 3 if gaps.size == 0 else int(np.clip(np.ceil(-np.log10(gaps.min())) + 1, 3, 6))
    return [f"{x:.{decimals}f}" for x in v]


def _via_point_study(n_via: Sequence[int], energy_ratio, perturbation_ratio) -> Figure:
    counts, e, p = _study_arrays("n_via", n_via, energy_ratio, perturbation_ratio)
    if np.any(counts < 0) or np.any(counts != np.round(counts)):
        raise FigureError("n_via", n_via, f"n_via={list(n_via)!r}: numbers of via points are integers >= 0")
    if np.unique(counts).size != counts.size:
        raise FigureError("n_via", n_via, f"n_via={list(n_via)!r}: each number of via points may appear once")
    with _styled():
        fig, axes = _new_figure(1, 2, height=3.2, width=STYLE["width"] * 1.25, sharex=False)
        ylabels = (r"$J_e / J_{e0}$ [-]", r"$J_\varphi / J_{\varphi 0}$ [-]")
        for ax, ratio, ylabel in zip(axes, (e, p), ylabels, strict=True):
            ax.axhline(1.0, color=STYLE["reference_color"], linestyle=STYLE["reference_style"],
                       linewidth=STYLE["thin_width"], label="no via point (ratio 1)", zorder=1)
            bars = ax.bar(counts, ratio, width=0.6, color=STYLE["plan_color"], zorder=2)
            ax.bar_label(bars, labels=_value_labels(ratio), fontsize=STYLE["legend_size"])
            ax.set_xticks(counts)
            ax.set_xlabel(r"number of via points per segment $n_{vp}$ [-]")
            ax.set_ylabel(ylabel)
            ax.set_ylim(0.0, 1.15 * max(1.0, float(ratio.max())))
        return _finish(fig, "Fig. 3.7-3.8 — energy and perturbation against the number of via points", axes)


def via_point_study_figure(path: str | Path, n_via: Sequence[int], energy_ratio, perturbation_ratio) -> Path:
    """Write Fig. 3.7-3.8: J_e / J_e0 and J_phi / J_phi0 against the number of via points (bars).

    J_e0, J_phi0 are the indices without via points (seed 3.2.5); the ratios are dimensionless.

    Args:
        path: the PNG file to write (its folder is created if needed).
        n_via: numbers of via points per segment, distinct integers >= 0, shape (k,).
        energy_ratio: J_e / J_e0 of each case, shape (k,) [-].
        perturbation_ratio: J_phi / J_phi0 of each case, shape (k,) [-].

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        FigureError: mismatched lengths, non-finite inputs, bad counts, a suffix other than .png.
        ShapeError: an input that is empty or not 1-D.
    """
    target = _png_path(path)
    return _save_to_file(_via_point_study(n_via, energy_ratio, perturbation_ratio), target)


def _alpha_study(alphas, energy_ratio, perturbation_ratio) -> Figure:
    a, e, p = _study_arrays("alphas", alphas, energy_ratio, perturbation_ratio)
    if np.any((a < 0) | (a > 1)):
        raise FigureError("alphas", alphas, f"alphas={a.tolist()!r}: the weight alpha of seed 3.26 lies in "
                                            "[0, 1]")
    order = np.argsort(a, kind="stable")
    with _styled():
        fig, axes = _new_figure(1, 2, height=3.2, width=STYLE["width"] * 1.25, sharex=False)
        specs = ((e, r"$J_e / J_e|_{\alpha=0}$ [-]"), (p, r"$J_\varphi / J_\varphi|_{\alpha=1}$ [-]"))
        for ax, (ratio, ylabel) in zip(axes, specs, strict=True):
            ax.plot(a[order], ratio[order], marker="o", color=STYLE["plan_color"],
                    linewidth=STYLE["line_width"], label="optimised")
            ax.set_xlabel(r"weight $\alpha$ [-]")
            ax.set_ylabel(ylabel)
            ax.set_xlim(-0.05, 1.05)
        return _finish(fig, r"Fig. 3.9-3.10 — energy and perturbation against the weight $\alpha$", axes)


def alpha_study_figure(path: str | Path, alphas, energy_ratio, perturbation_ratio) -> Path:
    """Write Fig. 3.9-3.10: J_e / J_e|alpha=0 and J_phi / J_phi|alpha=1 against alpha (markers + lines).

    Args:
        path: the PNG file to write (its folder is created if needed).
        alphas: weights alpha of the objective (seed 3.26), each in [0, 1], shape (k,) [-].
        energy_ratio: J_e / J_e|alpha=0 of each case, shape (k,) [-].
        perturbation_ratio: J_phi / J_phi|alpha=1 of each case, shape (k,) [-].

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        FigureError: mismatched lengths, non-finite inputs, alpha outside [0, 1], a suffix other
            than .png.
        ShapeError: an input that is empty or not 1-D.
    """
    target = _png_path(path)
    return _save_to_file(_alpha_study(alphas, energy_ratio, perturbation_ratio), target)




def _appendix(path: str, coordinates: str, energy: str, perturbation: str) -> dict[str, str]:
    other = "Appendix (cf. 3.2.6, Fig. 3.15-3.18)"
    return {"path": f"Appendix, Fig. {path}", "coordinates": f"Appendix, Fig. {coordinates}",
            "energy": f"Appendix, Fig. {energy}", "perturbation": f"Appendix, Fig. {perturbation}",
            "thrust": other, "roll": other,
            "rotor_speeds": "Appendix (eq. 3.48)", "rotor_forces": "Appendix (eq. 3.48)"}


#: The thesis figures of the appendix' comparison (the square mission planned by the original 1-step method and by
#: the 2-step one), by method, for :func:`fpr.views.figures.plan_figures`'s ``figure_numbers``.
APPENDIX_FIGURES = {"one-step": _appendix("4.11", "4.13", "4.15", "4.17"),
                    "two-step": _appendix("4.12", "4.14", "4.16", "4.18")}
