"""Meshcat scenes of the FPR and its prototype: see :mod:`fpr.views.scene.builder`."""

from fpr.views.scene import builder as _builder


def __getattr__(name):
    return getattr(_builder, name)
