"""The benchmark, ``python -m fpr.bench``: one module per section (:mod:`~fpr.cli.bench.model`,
:mod:`~fpr.cli.bench.planning`, :mod:`~fpr.cli.bench.control`), the timing loops
(:mod:`~fpr.cli.bench.timing`) and the command line (:mod:`~fpr.cli.bench.cli`, :func:`main`).
"""

from fpr.cli.bench.cli import main

__all__ = ["main"]
