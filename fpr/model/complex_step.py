"""Complex-step copies (:func:`complex_step_copies`): batches made of copies of one batch whose real parts are
equal (each copy's perturbation in its imaginary part only), so that their real work is done once
(:func:`fpr.model.jets.inverse`, :func:`fpr.model.jets.solve_matrices`,
:func:`fpr.model.jets.sin_cos_value`)."""
import contextvars
from contextlib import contextmanager

import numpy as np

_COPIES = contextvars.ContextVar("complex_step_copies", default=0)


@contextmanager
def complex_step_copies(count: int):
    """Within the block, complex batches whose leading axis is ``count`` copies of one batch (copy-major)
    with equal real parts (complex-step copies: each copy's perturbation is in its imaginary part only, e.g.
    :meth:`planners.problem.motion.MotionProblem.evaluate`'s) have their matrices inverted once, not once per copy
    (:func:`fpr.model.jets.inverse`, :func:`fpr.model.jets.solve_matrices`). A batch whose real parts differ
    is inverted as it is."""
    token = _COPIES.set(int(count))
    try:
        yield
    finally:
        _COPIES.reset(token)


def equal_copies(x):
    """A real array whose leading axis is :func:`complex_step_copies`' copies of one block, as
    (count, block...), when all the copies are equal; else None."""
    count = _COPIES.get()
    if count < 2 or x.ndim == 0 or x.shape[0] % count:
        return None
    blocks = x.reshape((count, -1) + x.shape[1:])
    return blocks if (blocks == blocks[:1]).all() else None


def shared_real(a):
    """``(count, real part of one copy, imaginary parts (count, ...))`` of a complex batch of matrices
    (..., n, n) made of :func:`complex_step_copies`' copies with equal real parts, else None."""
    if not np.iscomplexobj(a) or a.ndim < 3:
        return None
    re = equal_copies(a.real)
    if re is None:
        return None
    return re.shape[0], re[0], a.imag.reshape(re.shape)


def shared_sin_cos(x):
    """``(np.sin(x), np.cos(x))`` of a real array; when its leading axis is :func:`complex_step_copies`'
    copies of one block (the real parts of complex-step copies), from that block's (the same bits, a fraction
    of the work)."""
    blocks = equal_copies(x)
    if blocks is not None:
        s, c = np.sin(blocks[0]), np.cos(blocks[0])
        return (np.broadcast_to(s, blocks.shape).reshape(x.shape),
                np.broadcast_to(c, blocks.shape).reshape(x.shape))
    return np.sin(x), np.cos(x)


__all__ = ["complex_step_copies", "shared_real", "shared_sin_cos"]
