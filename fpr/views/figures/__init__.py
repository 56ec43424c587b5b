"""Figures of the thesis (seed 3.2.5-3.3.2, ch. 4), written as PNG files: see :mod:`fpr.views.figures.planning`."""

from fpr.views.figures import planning as _planning


def __getattr__(name):
    return getattr(_planning, name)
