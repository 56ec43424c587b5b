"""Build of the optional C extensions of the closed loop's tick: ``controllers._alloc`` (the
allocation tick), ``fpr.model._attitude`` (the numpy part of ``Robot.attitude_model``) and ``fpr.sim._watch``
(the watch's screen); everything else is in pyproject.toml. ``optional=True``: without a C compiler ``pip
install`` still succeeds and :class:`controllers.allocation.Allocator`,
:meth:`fpr.model.robot.Robot.attitude_model`, :class:`fpr.sim.watch.Watch` and :class:`fpr.sim.plant.Plant` use
their Python paths. After
changing a C source: ``python setup.py build_ext --inplace``. ``-ffp-contract=off``: no fused multiply-adds, so
that the C code rounds as its Python reference does, operation by operation."""

import numpy
from setuptools import Extension, setup

setup(ext_modules=[Extension(name, [source], include_dirs=[numpy.get_include(), "."], depends=["fpr/model/_dense.h"],
                             extra_compile_args=["-O2", "-ffp-contract=off"], optional=True)
                   for name, source in (("controllers._alloc", "controllers/_alloc.c"),
                                        ("fpr.model._attitude", "fpr/model/_attitude.c"),
                                        ("fpr.sim._watch", "fpr/sim/_watch.c"),
                                        ("fpr.model._multibody", "fpr/model/_multibody.c"),
                                        ("fpr.model._jets", "fpr/model/_jets.c"))])
