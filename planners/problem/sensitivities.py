"""A motion's node quantities and their sensitivities to each node's motion jet, the two ways
:meth:`planners.problem.motion.MotionProblem._node_derivatives` takes them.

Both take ``quantities`` (the problem's ``_quantities``: motion (5, N, n) -> (raw (N, Q), rows (N, R))) and
the motion, and return (raw, rows, d raw / d X (N, Q, r, j), d rows / d X (N, R, r, j)), X[r, i, j] the r-th
derivative of coordinate j at node i, for the D = 5 n directions (r, j):

* :func:`by_dual_numbers`: one pass on dual numbers (:mod:`fpr.model.dual`), the value once and the D
  directions as real tangents (each quantity carrying only the directions it depends on);
* :func:`by_complex_step`: D complex-step copies of the motion (copy-major along the node axis), each with one
  entry perturbed by i h: the independent reference the tests hold the dual numbers to.
"""
from itertools import product

import numpy as np

from fpr.model.dual import Dual


def _arranged(per_direction, n_r, n, n_s):
    """Sensitivities (D, N, Q), D = (r, j) r-major, arranged (N, Q, r, j)."""
    return per_direction.reshape(n_r, n, n_s, -1).transpose(2, 3, 0, 1)


def seeded_motion(motion, step: float | None = None):
    """What the quantities take: the Dual motion seeded with the D directions, or with a ``step``, the
    complex-step copies (5, D N, n) (module docstring).
    """
    n_r, _, n = motion.shape
    directions = list(product(range(n_r), range(n)))
    if step is None:
        return Dual.seeded(motion, [(r, slice(None), j) for r, j in directions])
    big = np.repeat(motion[:, None].astype(complex), len(directions), axis=1)  # (5, D, N, n)
    for d, (r, j) in enumerate(directions):
        big[r, d, :, j] += 1j * step
    return big.reshape(n_r, -1, n)


def by_dual_numbers(quantities, motion):
    """The quantities and their sensitivities by dual numbers (module docstring)."""
    n_r, n_s, n = motion.shape
    directions = n_r * n
    raw, rows = quantities(seeded_motion(motion))
    return (raw.value, rows.value, _arranged(raw.full_tangents(directions), n_r, n, n_s),
            _arranged(rows.full_tangents(directions), n_r, n, n_s))


def by_complex_step(quantities, motion, step: float):
    """The quantities and their sensitivities by complex step of size ``step`` (module docstring)."""
    n_r, n_s, n = motion.shape
    raw, rows = quantities(seeded_motion(motion, step))
    return (raw[:n_s].real, rows[:n_s].real, _arranged(raw.imag / step, n_r, n, n_s),
            _arranged(rows.imag / step, n_r, n, n_s))


__all__ = ["by_complex_step", "by_dual_numbers", "seeded_motion"]
