"""Forward-mode dual numbers: an array's value and its derivatives along D directions, computed together.

A :class:`Dual` holds ``value`` (a real array of shape S) and ``tangents`` (shape (D,) + S): the derivatives of
the value along D directions of some input. Arithmetic, the elementary functions the models use and numpy's
array functions on a Dual propagate the tangents exactly (first order), through numpy's protocols
(``__array_ufunc__``, ``__array_function__``), so the models' numpy code runs on Duals as it is where it does
not allocate arrays itself (:func:`empty`, :func:`fpr.model.jets.inexact` take Duals).

This is what the planner's node sensitivities take instead of the complex step
(:meth:`planners.problem.MotionProblem._node_derivatives`): the value is computed once, not once per direction,
and the tangents in real arithmetic. Comparisons compare values; ``.real`` is the value (code that compares the
real parts of complex-step values compares a Dual's values).

Example:
    >>> x = Dual(np.array([0.5, 1.0]), np.array([[1.0, 0.0], [0.0, 1.0]]))  # d/dx_0, d/dx_1
    >>> y = np.sin(x) * x
    >>> bool(np.allclose(y.tangents[0, 0], np.cos(0.5) * 0.5 + np.sin(0.5)))
    True
"""
from __future__ import annotations

import numpy as np


class Dual:
    """A real array ``value`` (shape S) with its ``tangents`` (shape (D,) + S), D derivative directions."""

    __slots__ = ("value", "tangents")

    def __init__(self, value, tangents):
        self.value = value
        self.tangents = tangents

    @classmethod
    def seeded(cls, value, directions):
        """The Dual of ``value`` (shape S) whose tangent d is 1 at the entries ``directions[d]`` selects (an index
        into S, e.g. ``(r, slice(None), j)``) and 0 elsewhere."""
        value = np.asarray(value, dtype=float)
        tangents = np.zeros((len(directions),) + value.shape)
        for d, index in enumerate(directions):
            tangents[(d,) + tuple(index)] = 1.0
        return cls(value, tangents)

    shape = property(lambda self: self.value.shape)
    ndim = property(lambda self: self.value.ndim)
    size = property(lambda self: self.value.size)
    dtype = property(lambda self: self.value.dtype)
    directions = property(lambda self: self.tangents.shape[0], doc="D, the number of tangents.")
    real = property(lambda self: self.value, doc="The value (what complex-step code compares).")
    T = property(lambda self: Dual(self.value.T, np.moveaxis(self.tangents.T, -1, 0)))

    def __len__(self):
        return len(self.value)

    def __repr__(self):
        return f"Dual(shape={self.shape}, directions={self.directions})"

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        return Dual(self.value[key], self.tangents[(slice(None),) + key])

    def __setitem__(self, key, item):
        key = key if isinstance(key, tuple) else (key,)
        if isinstance(item, Dual):
            nd = self.value[key].ndim  # (a view for basic indices)
            self.value[key] = item.value
            self.tangents[(slice(None),) + key] = _pad(item, nd)
        else:
            self.value[key] = item
            self.tangents[(slice(None),) + key] = 0.0

    def reshape(self, *shape):
        shape = shape[0] if len(shape) == 1 and isinstance(shape[0], (tuple, list)) else shape
        value = self.value.reshape(shape)
        return Dual(value, self.tangents.reshape(self.tangents.shape[:1] + value.shape))

    def sum(self, axis=None, keepdims=False):
        if axis is None:
            axis = tuple(range(self.ndim))
        taxis = tuple(_tax(a) for a in axis) if isinstance(axis, tuple) else _tax(axis)
        return Dual(self.value.sum(axis=axis, keepdims=keepdims), self.tangents.sum(axis=taxis, keepdims=keepdims))

    def swapaxes(self, a, b):
        return Dual(np.swapaxes(self.value, a, b), np.swapaxes(self.tangents, _tax(a), _tax(b)))

    def copy(self):
        return Dual(self.value.copy(), self.tangents.copy())

    def astype(self, dtype, copy=True):
        if np.dtype(dtype).kind != "f":
            raise TypeError(f"a Dual has real values: cannot cast it to {dtype}")
        return self.copy() if copy else self

    # --- arithmetic (direct: the ufunc protocol's dispatch costs more) ---------------------------
    def __add__(self, other):
        return add(self, other)

    __radd__ = __add__

    def __sub__(self, other):
        return subtract(self, other)

    def __rsub__(self, other):
        return subtract(other, self)

    def __mul__(self, other):
        return multiply(self, other)

    __rmul__ = __mul__

    def __truediv__(self, other):
        return divide(self, other)

    def __rtruediv__(self, other):
        return divide(other, self)

    def __neg__(self):
        return Dual(-self.value, -self.tangents)

    def __pos__(self):
        return self

    def __pow__(self, p):
        if p == 2:
            return multiply(self, self)
        value = self.value ** p
        return Dual(value, self.tangents * (p * self.value ** (p - 1)))

    def __matmul__(self, other):
        return matmul(self, other)

    def __rmatmul__(self, other):
        return matmul(other, self)

    def __iadd__(self, other):
        return _inplace(self, add(self, other))

    def __isub__(self, other):
        return _inplace(self, subtract(self, other))

    def __imul__(self, other):
        return _inplace(self, multiply(self, other))

    def __itruediv__(self, other):
        return _inplace(self, divide(self, other))

    def __lt__(self, other):
        return self.value < _val(other)

    def __le__(self, other):
        return self.value <= _val(other)

    def __gt__(self, other):
        return self.value > _val(other)

    def __ge__(self, other):
        return self.value >= _val(other)

    # --- numpy's protocols ----------------------------------------------------------------------
    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        out = kwargs.pop("out", None)
        if method == "reduce" and ufunc is np.add and not kwargs.get("where", None) is not None:
            x = inputs[0]
            result = x.sum(axis=kwargs.get("axis", 0), keepdims=kwargs.get("keepdims", False))
        elif method != "__call__" or kwargs or ufunc not in _UFUNCS:
            return NotImplemented
        else:
            result = _UFUNCS[ufunc](*inputs)
        if out is None:
            return result
        return _inplace(out[0], result)

    def __array_function__(self, func, types, args, kwargs):
        handler = _FUNCTIONS.get(func)
        if handler is None:
            return NotImplemented
        return handler(*args, **kwargs)


def _inplace(out, result):
    """Write ``result`` into ``out`` (a Dual, or an array when ``result`` is one), return ``out``."""
    if isinstance(out, Dual):
        out.value[...] = _val(result)
        out.tangents[...] = _pad(result, out.ndim) if isinstance(result, Dual) else 0.0
        return out
    if isinstance(result, Dual):
        raise TypeError("a Dual result cannot be written into a plain array")
    out[...] = result
    return out


def _val(x):
    """The value of a Dual, else ``x`` itself."""
    return x.value if isinstance(x, Dual) else x


def _tax(axis):
    """The tangents' axis of a value's axis."""
    return axis + 1 if axis >= 0 else axis


def _pad(x: Dual, ndim: int):
    """x's tangents with unit axes after the direction axis, for its value to have ``ndim`` dims (broadcasting
    against values of ``ndim`` dims then lines up)."""
    t = x.tangents
    extra = ndim - x.value.ndim
    return t.reshape(t.shape[:1] + (1,) * extra + t.shape[1:]) if extra > 0 else t


def _full(t, shape):
    """Tangents ``t`` broadcast to (D,) + ``shape`` (a copy when broadcasting adds entries: results stay
    writable)."""
    full = t.shape[:1] + tuple(shape)
    return t if t.shape == full else np.broadcast_to(t, full).copy()


def add(a, b):
    if isinstance(a, Dual) and isinstance(b, Dual):
        value = a.value + b.value
        nd = value.ndim
        return Dual(value, _full(_pad(a, nd) + _pad(b, nd), value.shape))
    x, c = (a, b) if isinstance(a, Dual) else (b, a)
    value = a.value + c if x is a else c + b.value
    return Dual(value, _full(_pad(x, value.ndim), value.shape))


def subtract(a, b):
    if isinstance(b, Dual):
        return add(a, -b)
    value = a.value - b
    return Dual(value, _full(_pad(a, value.ndim), value.shape))


def multiply(a, b):
    if isinstance(a, Dual) and isinstance(b, Dual):
        value = a.value * b.value
        nd = value.ndim
        t, u = _pad(a, nd) * b.value, _pad(b, nd) * a.value
        if t.shape == u.shape:
            t += u
        else:  # one operand's tangents broadcast the other's
            t = t + u
        return Dual(value, t)
    x, c = (a, b) if isinstance(a, Dual) else (b, a)
    c = np.asarray(c)
    value = x.value * c
    return Dual(value, _full(_pad(x, value.ndim) * c, value.shape))


def divide(a, b):
    if not isinstance(b, Dual):
        b = np.asarray(b)
        value = a.value / b
        return Dual(value, _full(_pad(a, value.ndim) / b, value.shape))
    value = _val(a) / b.value
    nd = value.ndim
    t = _pad(b, nd) * (-value)
    if isinstance(a, Dual):
        t = t + _pad(a, nd)
    return Dual(value, _full(t / b.value, value.shape))


def matmul(a, b):
    """a @ b with numpy's semantics (1-D operands are vectors)."""
    av, bv = _val(a), _val(b)
    value = np.matmul(av, bv)
    parts = []
    if isinstance(a, Dual):
        at = a.tangents if a.ndim > 1 else a.tangents[:, None, :]  # rows: keep them matrices
        t = np.matmul(at, bv if np.ndim(bv) > 1 else np.asarray(bv)[:, None])
        if a.ndim == 1:
            t = t[..., 0, :] if np.ndim(bv) > 1 else t[..., 0, 0]
        elif np.ndim(bv) == 1:
            t = t[..., 0]
        parts.append(t)
    if isinstance(b, Dual):
        bt = b.tangents if b.ndim > 1 else b.tangents[..., None]
        t = np.matmul(av if np.ndim(av) > 1 else np.asarray(av)[None, :], bt)
        if b.ndim == 1:
            t = t[..., 0] if np.ndim(av) > 1 else t[..., 0, 0]
        elif np.ndim(av) == 1:
            t = t[..., 0, :]
        parts.append(t)
    nd = value.ndim
    t = sum(p.reshape(p.shape[:1] + (1,) * (nd + 1 - p.ndim) + p.shape[1:]) for p in parts)
    return Dual(value, _full(t, value.shape))


def _chain(x, value, derivative):
    """The Dual of a function's ``value`` at x with the derivative ``derivative`` (elementwise)."""
    return Dual(value, x.tangents * derivative)


def _sin(x):
    return _chain(x, np.sin(x.value), np.cos(x.value))


def _cos(x):
    return _chain(x, np.cos(x.value), -np.sin(x.value))


def _sqrt(x):
    value = np.sqrt(x.value)
    return Dual(value, x.tangents / (2.0 * value))


def _arctan2(y, x):
    yv, xv = _val(y), _val(x)
    value = np.arctan2(yv, xv)
    nd = value.ndim
    scale = 1.0 / (xv * xv + yv * yv)
    t = 0.0
    if isinstance(y, Dual):
        t = _pad(y, nd) * (xv * scale)
    if isinstance(x, Dual):
        t = t - _pad(x, nd) * (yv * scale)
    return Dual(value, _full(t, value.shape))


def _absolute(x):
    return _chain(x, np.abs(x.value), np.sign(x.value))


def _compare(op):
    return lambda a, b: op(_val(a), _val(b))


_UFUNCS = {
    np.add: add, np.subtract: subtract, np.multiply: multiply, np.true_divide: divide, np.matmul: matmul,
    np.negative: lambda x: -x, np.positive: lambda x: x, np.sin: _sin, np.cos: _cos, np.sqrt: _sqrt,
    np.arctan2: _arctan2, np.absolute: _absolute, np.square: lambda x: multiply(x, x),
    np.sign: lambda x: np.sign(x.value),
    np.less: _compare(np.less), np.less_equal: _compare(np.less_equal), np.greater: _compare(np.greater),
    np.greater_equal: _compare(np.greater_equal), np.equal: _compare(np.equal),
    np.not_equal: _compare(np.not_equal),
}


# --- array functions ------------------------------------------------------------------------------
def directions_of(items) -> int:
    """D of the first Dual among ``items``."""
    return next(x.directions for x in items if isinstance(x, Dual))


def lift(x, directions: int, dtype=float) -> Dual:
    """``x`` as a Dual (a constant: zero tangents) with ``directions`` tangents."""
    if isinstance(x, Dual):
        return x
    x = np.asarray(x, dtype=dtype)
    return Dual(x, np.zeros((directions,) + x.shape))


def _lifted(items):
    d = directions_of(items)
    return [lift(x, d) for x in items]


def _concatenate(items, axis=0, out=None, **kwargs):
    items = _lifted(list(items))
    return Dual(np.concatenate([x.value for x in items], axis=axis),
                np.concatenate([x.tangents for x in items], axis=_tax(axis)))


def _stack(items, axis=0, out=None, **kwargs):
    items = _lifted(list(items))
    shape = np.broadcast_shapes(*(x.shape for x in items))
    if any(x.shape != shape for x in items):
        items = [_broadcast_to(x, shape) for x in items]
    return Dual(np.stack([x.value for x in items], axis=axis),
                np.stack([x.tangents for x in items], axis=_tax(axis)))


def _broadcast_to(x, shape, subok=False):
    shape = tuple(shape) if np.iterable(shape) else (shape,)
    if not isinstance(x, Dual):
        return np.broadcast_to(x, shape)
    return Dual(np.broadcast_to(x.value, shape), np.broadcast_to(_pad(x, len(shape)), x.tangents.shape[:1] + shape))


def _broadcast_arrays(*items, subok=False):
    shape = np.broadcast_shapes(*(np.shape(x) for x in items))
    return [_broadcast_to(x, shape) for x in items]


def _where(condition, a, b):
    condition = _val(condition)
    value = np.where(condition, _val(a), _val(b))
    ta = _pad(a, value.ndim) if isinstance(a, Dual) else 0.0
    tb = _pad(b, value.ndim) if isinstance(b, Dual) else 0.0
    return Dual(value, _full(np.where(condition, ta, tb), value.shape))


def _sum(x, axis=None, dtype=None, out=None, keepdims=False, **kwargs):
    return x.sum(axis=axis, keepdims=keepdims)


def _take(x, indices, axis=None, out=None, mode="raise"):
    if axis is None:
        return _take(x.reshape(-1), indices, 0)
    return Dual(np.take(x.value, indices, axis=axis), np.take(x.tangents, indices, axis=_tax(axis)))


def _dot(a, b, out=None):
    if np.ndim(_val(a)) <= 2 and np.ndim(_val(b)) <= 2:
        return matmul(a, b) if np.ndim(_val(a)) and np.ndim(_val(b)) else multiply(a, b)
    raise NotImplementedError("np.dot of Duals beyond matrices")


def _reshape(x, shape=None, order="C", **kwargs):
    return x.reshape(shape if shape is not None else kwargs["newshape"])


def _swapaxes(x, a, b):
    return x.swapaxes(a, b)


def _empty_like(x, dtype=None, order="K", subok=True, shape=None, **kwargs):
    value = np.empty(x.shape if shape is None else shape)
    return Dual(value, np.empty((x.directions,) + value.shape))


def _zeros_like(x, dtype=None, order="K", subok=True, shape=None, **kwargs):
    value = np.zeros(x.shape if shape is None else shape)
    return Dual(value, np.zeros((x.directions,) + value.shape))


def _result_type(*items):
    return np.result_type(*(x.value if isinstance(x, Dual) else x for x in items))


def _tile(x, reps):
    reps = tuple(reps) if np.iterable(reps) else (reps,)
    value = np.tile(x.value, reps)
    reps = (1,) * (value.ndim - len(reps)) + reps
    return Dual(value, np.tile(_pad(x, value.ndim), (1,) + reps))


def _ascontiguous(x, dtype=None, **kwargs):
    return Dual(np.ascontiguousarray(x.value), np.ascontiguousarray(x.tangents))


_FUNCTIONS = {
    np.concatenate: _concatenate, np.stack: _stack, np.broadcast_to: _broadcast_to,
    np.broadcast_arrays: _broadcast_arrays, np.where: _where, np.sum: _sum, np.take: _take, np.dot: _dot,
    np.reshape: _reshape, np.swapaxes: _swapaxes, np.empty_like: _empty_like, np.zeros_like: _zeros_like,
    np.result_type: _result_type, np.tile: _tile, np.ascontiguousarray: _ascontiguous,
    np.ndim: lambda x: x.ndim, np.shape: lambda x: x.shape, np.size: lambda x, axis=None: np.size(x.value, axis),
    np.iscomplexobj: lambda x: False, np.real: lambda x: x.value, np.matmul: matmul,
}


def empty(shape, *like) -> np.ndarray | Dual:
    """``np.empty(shape)`` of floats, a Dual (the D of the first Dual among ``like``) when ``like`` holds one."""
    for x in like:
        if isinstance(x, Dual):
            return Dual(np.empty(shape), np.empty((x.directions,) + tuple(shape)))
    return np.empty(shape, np.result_type(*like, float))


def zeros(shape, *like) -> np.ndarray | Dual:
    """``np.zeros(shape)`` (as :func:`empty`)."""
    for x in like:
        if isinstance(x, Dual):
            return Dual(np.zeros(shape), np.zeros((x.directions,) + tuple(shape)))
    return np.zeros(shape, np.result_type(*like, float))


__all__ = ["Dual", "empty", "lift", "zeros"]
