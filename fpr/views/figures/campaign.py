"""Figures of a robustness campaign (:mod:`fpr.robustness`): success against each varied quantity, and
histograms of the outcomes.

* ``campaign_success.png``: one panel per varied column; each run is a dot at its sampled value, at 1
  (success) or 0 (failure), jittered a little vertically; the line is the success rate in bins holding equal
  numbers of runs, with its 95 % Wilson interval as error bars.
* ``campaign_outcomes.png``: one histogram per numeric outcome (largest tracking error of each coordinate,
  least ground clearance, saturated ticks, peak rotor speed), successes and failures stacked; the rotor
  speed panel shows w_max as a limit line.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fpr.robustness.spec import unit
from fpr.robustness.summary import wilson_interval
from fpr.views.figures.style import STYLE, _finish, _limit, _new_figure, _save_to_file, _styled

#: Most major ticks on an x axis: the panels are narrow, and a sampled quantity's ticks are long (-0.025).
X_TICKS = 5

HISTOGRAMS = ("least_clearance_m", "saturated_ticks", "peak_rotor_speed_rad_s")
"""Outcome columns drawn as histograms (after the ``max_error_<coordinate>`` ones)."""


def _binned(x: np.ndarray, ok: np.ndarray, bins: int):
    """Success rate in ``bins`` bins of equal counts: centres, rates, lower and upper error bars."""
    order = np.argsort(x, kind="stable")
    centres, rates, low, high = [], [], [], []
    for part in np.array_split(order, bins):
        if not part.size:
            continue
        k, n = int(ok[part].sum()), part.size
        lo, hi = wilson_interval(k, n)
        centres.append(float(np.mean(x[part])))
        rates.append(k / n)
        low.append(k / n - lo)
        high.append(hi - k / n)
    # the Wilson bounds of 0 or n successes equal the rate only to round-off: matplotlib refuses a bar of -1e-17
    return np.array(centres), np.array(rates), np.maximum(np.array([low, high]), 0.0)


def _label(name: str) -> str:
    """An axis label: the column's name and its unit (:func:`fpr.robustness.spec.unit`)."""
    found = unit(name)
    return f"{name} [{found}]" if found else name


def _x_axis(ax, name: str) -> None:
    """The column's label with its unit, at most :data:`X_TICKS` ticks."""
    from matplotlib.ticker import MaxNLocator

    ax.set_xlabel(_label(name))
    ax.xaxis.set_major_locator(MaxNLocator(nbins=X_TICKS))


def success_figure(rows: list[dict], varied: list[str], title: str = ""):
    """Success against each varied column (see the module docstring); a Figure."""
    with _styled():
        return _success_figure(rows, varied, title)


def _success_figure(rows: list[dict], varied: list[str], title: str):
    n = max(len(varied), 1)
    cols = 2 if n > 1 else 1
    fig, axes = _new_figure(math.ceil(n / cols), cols, sharex=False, width=STYLE["width"] * 1.25)
    ok = np.array([bool(r["success"]) for r in rows])
    jitter = np.random.default_rng(0).uniform(-0.04, 0.04, ok.size)
    bins = max(2, min(10, ok.size // 10))
    for ax, name in zip(axes[:len(varied)], varied, strict=True):
        x = np.array([float(r[name]) for r in rows])
        ax.scatter(x, ok + jitter, s=6, color=np.where(ok, "tab:green", "tab:red"), alpha=0.5, linewidths=0)
        if np.ptp(x) > 0 and ok.size >= 4:
            centres, rates, bars = _binned(x, ok, bins)
            ax.errorbar(centres, rates, yerr=bars, color=STYLE["plan_color"], marker="o", capsize=2,
                        label="success rate (95 % Wilson)")
        _x_axis(ax, name)
        ax.set_ylim(-0.1, 1.1)
        ax.set_ylabel("success")
    for ax in axes[len(varied):]:
        ax.set_visible(False)
    # one legend, beside the last column's first panel: a legend beside a left-column panel would cover the
    # panel on its right (every panel has the same labels)
    return _finish(fig, title or f"success against the varied quantities ({ok.sum()} of {ok.size} runs)",
                   axes[cols - 1:cols] if len(varied) >= cols else axes[:1])


def outcomes_figure(rows: list[dict], chain: list[str], max_speed: float | None = None, title: str = ""):
    """Histograms of the numeric outcomes, successes and failures stacked; a Figure."""
    with _styled():
        return _outcomes_figure(rows, chain, max_speed, title)


def _outcomes_figure(rows: list[dict], chain: list[str], max_speed: float | None, title: str):
    from matplotlib.ticker import MaxNLocator

    names = [f"max_error_{c}" for c in chain] + list(HISTOGRAMS)
    cols = 2
    fig, axes = _new_figure(math.ceil(len(names) / cols), cols, sharex=False, width=STYLE["width"] * 1.25)
    good = [r for r in rows if not r["error"]]
    for ax, name in zip(axes[:len(names)], names, strict=True):
        values = [np.array([float(r[name]) for r in good if bool(r["success"]) == s]) for s in (True, False)]
        values = [v[np.isfinite(v)] for v in values]
        if sum(v.size for v in values):
            ax.hist(values, bins=20, stacked=True, color=["tab:green", "tab:red"], label=["success", "failure"])
        if name == "peak_rotor_speed_rad_s" and max_speed is not None:
            _limit(ax, max_speed, vertical=True)
        _x_axis(ax, name)
        ax.set_ylabel("runs")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    for ax in axes[len(names):]:
        ax.set_visible(False)
    return _finish(fig, title or f"outcomes of {len(good)} runs", axes[cols - 1:cols])  # see success_figure


def campaign_figures(out, rows: list[dict], varied: list[str], chain: list[str],
                     max_speed: float | None = None) -> list[Path]:
    """Write ``campaign_success.png`` (when something is varied) and ``campaign_outcomes.png`` into ``out``."""
    out = Path(out)
    written = []
    if varied:
        written.append(_save_to_file(success_figure(rows, varied), out / "campaign_success.png"))
    written.append(_save_to_file(outcomes_figure(rows, chain, max_speed), out / "campaign_outcomes.png"))
    return written
