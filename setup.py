"""Build of the optional C extension ``controllers._alloc`` (the allocation tick, issue 13); everything else
is in pyproject.toml. ``optional=True``: without a C compiler ``pip install`` still succeeds and
:class:`controllers.allocation.Allocator` uses its Python path. After changing the C source:
``python setup.py build_ext --inplace``."""

import numpy
from setuptools import Extension, setup

setup(ext_modules=[Extension("controllers._alloc", ["controllers/_alloc.c"],
                             include_dirs=[numpy.get_include()], extra_compile_args=["-O2"], optional=True)])
