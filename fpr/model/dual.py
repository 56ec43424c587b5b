"""Forward-mode dual numbers: an array's value and its derivatives along D directions, computed together.

A :class:`Dual` holds ``value`` (a real array of shape S) and ``tangents`` (shape (D,) + S): the derivatives
of the value along D directions of some input. Arithmetic, the elementary functions the models use and numpy's
array functions on a Dual propagate the tangents exactly (first order), through numpy's protocols
(``__array_ufunc__``, ``__array_function__``), so the models' numpy code runs on Duals as it is where it does
not allocate arrays itself (:func:`empty`, :func:`fpr.model.jets.inexact` take Duals).

This is what the planner's node sensitivities take instead of the complex step
(:meth:`planners.problem.motion.MotionProblem._node_derivatives`): the value is computed once, not once per
direction, and the tangents in real arithmetic. A Dual carries the tangents of the directions it depends on
only (``lo`` .. ``hi`` - 1: the planner's quantities depend on a part of the motion's derivative orders).
Comparisons compare values; ``.real`` is the value (code that compares the real parts of complex-step values
compares a Dual's values).

Example:
    >>> x = Dual(np.array([0.5, 1.0]), np.array([[1.0, 0.0], [0.0, 1.0]]))  # d/dx_0, d/dx_1
    >>> y = np.sin(x) * x
    >>> bool(np.allclose(y.tangents[0, 0], np.cos(0.5) * 0.5 + np.sin(0.5)))
    True
"""
from __future__ import annotations

import math

import numpy as np

_ALL = slice(None)

class Dual:
    """A real array ``value`` (shape S) with its derivatives along the directions ``lo .. lo + n - 1`` of D,
    ``tangents`` (shape (n,) + S); the derivatives along the other directions are 0 (a Dual that depends on a
    few of the inputs carries only their tangents; a constant none).

    ``bands`` (optional, of a seeded input): per index along the value's first axis, the range (lo, hi) of
    directions its tangents can be nonzero in; indexing the first axis then narrows the Dual to those (the
    planner's motion: the r-th derivative of s depends on the directions of order r only).
    """

    __slots__ = ("value", "tangents", "lo", "bands")

    def __init__(self, value, tangents, lo: int = 0, bands=None):
        self.value = value
        self.tangents = tangents
        self.lo = lo
        self.bands = bands

    @classmethod
    def seeded(cls, value, directions):
        """The Dual of ``value`` (shape S) whose tangent d is 1 at the entries ``directions[d]`` selects (an
        index into S whose first entry is an integer, e.g. ``(r, slice(None), j)``) and 0 elsewhere (with its
        ``bands``).
        """
        value = np.asarray(value, dtype=float)
        tangents = np.zeros((len(directions),) + value.shape)
        bands = [None] * len(value)
        for d, index in enumerate(directions):
            tangents[(d,) + tuple(index)] = 1.0
            lo, hi = bands[index[0]] or (d, d + 1)
            bands[index[0]] = (min(lo, d), max(hi, d + 1))
        return cls(value, tangents, 0, tuple(b or (0, 0) for b in bands))

    shape = property(lambda self: self.value.shape)
    ndim = property(lambda self: self.value.ndim)
    size = property(lambda self: self.value.size)
    dtype = property(lambda self: self.value.dtype)
    hi = property(lambda self: self.lo + self.tangents.shape[0], doc="One past the last direction carried.")
    real = property(lambda self: self.value, doc="The value (what complex-step code compares).")
    T = property(lambda self: Dual(self.value.T, np.moveaxis(self.tangents.T, -1, 0), self.lo))

    def full_tangents(self, directions: int) -> np.ndarray:
        """The tangents along all D = ``directions`` directions, shape (D,) + S."""
        if self.lo == 0 and self.tangents.shape[0] == directions:
            return self.tangents
        out = np.zeros((directions,) + self.shape)
        out[self.lo:self.hi] = self.tangents
        return out

    def __array__(self, dtype=None, copy=None):
        raise TypeError("a Dual is not an array: take its .value (or make the code take Duals)")

    def __len__(self):
        return len(self.value)

    def __repr__(self):
        return f"Dual(shape={self.shape}, directions={self.lo}..{self.hi - 1})"

    def __getitem__(self, key):
        if self.bands is None:  # (the frequent case, first)
            return Dual(self.value[key], self.tangents[(_ALL,) + key if type(key) is tuple else (_ALL, key)],
                        self.lo)
        key = key if isinstance(key, tuple) else (key,)
        if self.bands is not None and key and isinstance(key[0], (int, np.integer, slice)):
            rows = range(len(self.bands))[key[0]]
            bands = [self.bands[r] for r in (rows if isinstance(rows, range) else [rows])]
            bands = [b for b in bands if b[1] > b[0]]
            lo = min((b[0] for b in bands), default=0)
            hi = max((b[1] for b in bands), default=0)
            tangents = self.tangents[lo - self.lo:hi - self.lo][(slice(None),) + key]
            kept = tuple(self.bands[r] for r in rows) if isinstance(rows, range) else None
            return Dual(self.value[key], tangents, lo, kept if len(key) == 1 or all(
                isinstance(k, slice) and k == slice(None) for k in key[1:]) else None)
        return Dual(self.value[key], self.tangents[(slice(None),) + key], self.lo)

    def __setitem__(self, key, item):
        key = key if isinstance(key, tuple) else (key,)
        if isinstance(item, Dual):
            nd = self.value[key].ndim  # (a view for basic indices)
            self.value[key] = item.value
            if item.tangents.shape[0]:
                if item.lo < self.lo or item.hi > self.hi:
                    raise ValueError(f"directions {item.lo}..{item.hi - 1} assigned into a Dual of directions"
                                     f" {self.lo}..{self.hi - 1}: allocate it with all of its operands")
                target = self.tangents[item.lo - self.lo:item.hi - self.lo]
                if target.shape[0] != self.tangents.shape[0]:
                    self.tangents[(slice(None),) + key] = 0.0
                target[(slice(None),) + key] = _pad(item, nd)
            else:
                self.tangents[(slice(None),) + key] = 0.0
        else:
            self.value[key] = item
            self.tangents[(slice(None),) + key] = 0.0

    def reshape(self, *shape):
        """The Dual with its value reshaped to ``shape`` (a tuple or the sizes), as ``ndarray.reshape``."""
        shape = shape[0] if len(shape) == 1 and isinstance(shape[0], (tuple, list)) else shape
        value = self.value.reshape(shape)
        return Dual(value, self.tangents.reshape(self.tangents.shape[:1] + value.shape), self.lo)

    def sum(self, axis=None, keepdims=False):
        """The sum of the value over ``axis`` (an int, a tuple, or None for all), as ``ndarray.sum``."""
        if axis is None:
            axis = tuple(range(self.ndim))
        taxis = tuple(_tax(a) for a in axis) if isinstance(axis, tuple) else _tax(axis)
        t = self.tangents
        if not keepdims and t.ndim > 1 and taxis in (-1, t.ndim - 1) and t.shape[-1] <= 8:
            tangents = t @ np.ones(t.shape[-1])  # (numpy's reductions over a short last axis are slow)
        else:
            tangents = t.sum(axis=taxis, keepdims=keepdims)
        return Dual(self.value.sum(axis=axis, keepdims=keepdims), tangents, self.lo)

    def swapaxes(self, a, b):
        """The Dual with the value's axes ``a`` and ``b`` swapped, as ``ndarray.swapaxes``."""
        return Dual(np.swapaxes(self.value, a, b), np.swapaxes(self.tangents, _tax(a), _tax(b)), self.lo)

    def copy(self):
        """A copy of the value and the tangents (the copy carries no ``bands``)."""
        return Dual(self.value.copy(), self.tangents.copy(), self.lo)

    def astype(self, dtype, copy=True):
        """The Dual itself, or a copy of it with ``copy``, for a real ``dtype`` (the value keeps its float type).

        Raises:
            TypeError: ``dtype`` is not a real floating type.
        """
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
        return Dual(-self.value, -self.tangents, self.lo)

    def __pos__(self):
        return self

    def __pow__(self, p):
        if p == 2:
            return multiply(self, self)
        if p in (0, 1):
            return Dual(np.ones(self.shape), np.zeros(self.tangents.shape), self.lo) if p == 0 else self
        return Dual(self.value ** p, self.tangents * (p * self.value ** (p - 1)), self.lo)

    def __matmul__(self, other):
        return matmul(self, other)

    def __rmatmul__(self, other):
        return matmul(other, self)

    def __iadd__(self, other):
        return _update(self, add(self, other))

    def __isub__(self, other):
        return _update(self, subtract(self, other))

    def __imul__(self, other):
        return _update(self, multiply(self, other))

    def __itruediv__(self, other):
        return _update(self, divide(self, other))

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
        if method == "reduce" and ufunc is np.add and kwargs.get("where", None) is None:
            result = inputs[0].sum(axis=kwargs.get("axis", 0), keepdims=kwargs.get("keepdims", False))
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


def _update(x: Dual, result: Dual) -> Dual:
    """An in-place operator's result: written into ``x`` when x carries its directions, else ``result`` itself
    (the operator's name then refers to it).
    """
    if isinstance(result, Dual) and result.tangents.shape[0] and (result.lo < x.lo or result.hi > x.hi):
        return result
    return _inplace(x, result)


def _inplace(out, result):
    """Write ``result`` into ``out`` (a Dual, or an array when ``result`` is one), return ``out``."""
    if isinstance(out, Dual):
        out[...] = result
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
    against values of ``ndim`` dims then lines up).
    """
    t = x.tangents
    extra = ndim - x.value.ndim
    return t.reshape(t.shape[:1] + (1,) * extra + t.shape[1:]) if extra > 0 else t


def _full(t, shape):
    """Tangents ``t`` broadcast to (n,) + ``shape`` (a copy when broadcasting adds entries: results stay
    writable).
    """
    full = t.shape[:1] + tuple(shape)
    return t if t.shape == full else np.broadcast_to(t, full).copy()


def gather(value, parts) -> Dual:
    """The Dual of ``value`` whose tangents are the sum of ``parts``: (tangents (n_i, ...) broadcasting
    against ``value``, their first direction lo_i), over the directions any of them carries.
    """
    parts = [p for p in parts if p[0].shape[0]]
    if not parts:
        return Dual(value, np.zeros((0,) + value.shape))
    if len(parts) == 1:
        return Dual(value, _full(parts[0][0], value.shape), parts[0][1])
    lo = min(p[1] for p in parts)
    hi = max(p[1] + p[0].shape[0] for p in parts)
    if all(p[1] == lo and p[0].shape[0] == hi - lo for p in parts):
        t = parts[0][0] + parts[1][0]
        for p in parts[2:]:
            t = t + p[0] if t.shape != (hi - lo,) + value.shape else np.add(t, p[0], out=t)
        return Dual(value, _full(t, value.shape), lo)
    t = np.zeros((hi - lo,) + value.shape)
    for part, first in parts:
        t[first - lo:first - lo + part.shape[0]] += part
    return Dual(value, t, lo)


def add(a, b):
    if isinstance(a, Dual) and isinstance(b, Dual):
        value = a.value + b.value
        nd = value.ndim
        if a.lo == b.lo and a.tangents.shape[0] == b.tangents.shape[0]:
            return Dual(value, _full(_pad(a, nd) + _pad(b, nd), value.shape), a.lo)
        return gather(value, [(_pad(a, nd), a.lo), (_pad(b, nd), b.lo)])
    x, c = (a, b) if isinstance(a, Dual) else (b, a)
    value = a.value + c if x is a else c + b.value
    return Dual(value, _full(_pad(x, value.ndim), value.shape), x.lo)


def subtract(a, b):
    if isinstance(b, Dual):
        return add(a, -b)
    value = a.value - b
    return Dual(value, _full(_pad(a, value.ndim), value.shape), a.lo)


def multiply(a, b):
    if isinstance(a, Dual) and isinstance(b, Dual):
        value = a.value * b.value
        nd = value.ndim
        t, u = _pad(a, nd) * b.value, _pad(b, nd) * a.value
        if a.lo == b.lo and t.shape == u.shape:
            t += u
            return Dual(value, _full(t, value.shape), a.lo)
        return gather(value, [(t, a.lo), (u, b.lo)])
    x, c = (a, b) if isinstance(a, Dual) else (b, a)
    c = np.asarray(c)
    value = x.value * c
    return Dual(value, _full(_pad(x, value.ndim) * c, value.shape), x.lo)


def divide(a, b):
    if not isinstance(b, Dual):
        b = np.asarray(b)
        value = a.value / b
        return Dual(value, _full(_pad(a, value.ndim) / b, value.shape), a.lo)
    value = _val(a) / b.value
    nd = value.ndim
    parts = [(_pad(b, nd) * (-value / b.value), b.lo)]
    if isinstance(a, Dual):
        parts.append((_pad(a, nd) / b.value, a.lo))
    return gather(value, parts)


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
        parts.append((t, a.lo))
    if isinstance(b, Dual):
        bt = b.tangents if b.ndim > 1 else b.tangents[..., None]
        t = np.matmul(av if np.ndim(av) > 1 else np.asarray(av)[None, :], bt)
        if b.ndim == 1:
            t = t[..., 0] if np.ndim(av) > 1 else t[..., 0, 0]
        elif np.ndim(av) == 1:
            t = t[..., 0, :]
        parts.append((t, b.lo))
    nd = value.ndim
    return gather(value, [(t.reshape(t.shape[:1] + (1,) * (nd + 1 - t.ndim) + t.shape[1:]), lo)
                          for t, lo in parts])


def _chain(x, value, derivative):
    """The Dual of a function's ``value`` at x with the derivative ``derivative`` (elementwise)."""
    return Dual(value, x.tangents * derivative, x.lo)


def _sin(x):
    return _chain(x, np.sin(x.value), np.cos(x.value))


def _cos(x):
    return _chain(x, np.cos(x.value), -np.sin(x.value))


def _sqrt(x):
    value = np.sqrt(x.value)
    return Dual(value, x.tangents / (2.0 * value), x.lo)


def _arctan2(y, x):
    yv, xv = _val(y), _val(x)
    value = np.arctan2(yv, xv)
    nd = value.ndim
    scale = 1.0 / (xv * xv + yv * yv)
    parts = []
    if isinstance(y, Dual):
        parts.append((_pad(y, nd) * (xv * scale), y.lo))
    if isinstance(x, Dual):
        parts.append((_pad(x, nd) * (-yv * scale), x.lo))
    return gather(value, parts)


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
def span(*items) -> tuple[int, int]:
    """(lo, hi): the directions the Duals among ``items`` carry together ((0, 0) for none)."""
    ranges = [(x.lo, x.hi) for x in items if isinstance(x, Dual) and x.tangents.shape[0]]
    if not ranges:
        return 0, 0
    return min(r[0] for r in ranges), max(r[1] for r in ranges)


def lift(x, lo: int = 0, hi: int = 0) -> Dual:
    """``x`` as a Dual over the directions lo..hi-1 (a constant: zero tangents); a Dual over other directions
    is widened to them.
    """
    if isinstance(x, Dual):
        if x.lo == lo and x.hi == hi:
            return x
        t = np.zeros((hi - lo,) + x.shape)
        t[x.lo - lo:x.hi - lo] = x.tangents
        return Dual(x.value, t, lo)
    x = np.asarray(x, dtype=float)
    return Dual(x, np.zeros((hi - lo,) + x.shape), lo)


def _lifted(items):
    lo, hi = span(*items)
    return [lift(x, lo, hi) for x in items]


def _concatenate(items, axis=0, out=None, **kwargs):
    items = list(items)
    lo, hi = span(*items)
    value = np.concatenate([_val(x) for x in items], axis=axis)
    if all(isinstance(x, Dual) and x.lo == lo and x.tangents.shape[0] == hi - lo for x in items):
        return Dual(value, np.concatenate([x.tangents for x in items], axis=_tax(axis)), lo)
    # each item's tangents into its part of one zero array (no zero tangents of its own)
    tangents = np.zeros((hi - lo,) + value.shape)
    index = [slice(None)] * value.ndim
    start = 0
    axis = axis % value.ndim
    for x in items:
        size = np.shape(_val(x))[axis]
        if isinstance(x, Dual) and x.tangents.shape[0]:
            index[axis] = slice(start, start + size)
            tangents[(slice(x.lo - lo, x.hi - lo),) + tuple(index)] = x.tangents
        start += size
    return Dual(value, tangents, lo)


def _stack(items, axis=0, out=None, **kwargs):
    items = _lifted(list(items))
    shape = np.broadcast_shapes(*(x.shape for x in items))
    if any(x.shape != shape for x in items):
        items = [_broadcast_to(x, shape) for x in items]
    return Dual(np.stack([x.value for x in items], axis=axis),
                np.stack([x.tangents for x in items], axis=_tax(axis)), items[0].lo)


def _broadcast_to(x, shape, subok=False):
    shape = tuple(shape) if np.iterable(shape) else (shape,)
    if not isinstance(x, Dual):
        return np.broadcast_to(x, shape)
    tangents = np.broadcast_to(_pad(x, len(shape)), x.tangents.shape[:1] + shape)
    return Dual(np.broadcast_to(x.value, shape), tangents, x.lo)


def _broadcast_arrays(*items, subok=False):
    shape = np.broadcast_shapes(*(np.shape(x) for x in items))
    return [_broadcast_to(x, shape) for x in items]


def _where(condition, a, b):
    condition = _val(condition)
    value = np.where(condition, _val(a), _val(b))
    lo, hi = span(a, b)
    a, b = lift(a, lo, hi), lift(b, lo, hi)
    return Dual(value, _full(np.where(condition, _pad(a, value.ndim), _pad(b, value.ndim)), value.shape), lo)


def _sum(x, axis=None, dtype=None, out=None, keepdims=False, **kwargs):
    return x.sum(axis=axis, keepdims=keepdims)


def _take(x, indices, axis=None, out=None, mode="raise"):
    if axis is None:
        return _take(x.reshape(-1), indices, 0)
    return Dual(np.take(x.value, indices, axis=axis), np.take(x.tangents, indices, axis=_tax(axis)), x.lo)


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
    return Dual(value, np.empty(x.tangents.shape[:1] + value.shape), x.lo)


def _zeros_like(x, dtype=None, order="K", subok=True, shape=None, **kwargs):
    value = np.zeros(x.shape if shape is None else shape)
    return Dual(value, np.zeros(x.tangents.shape[:1] + value.shape), x.lo)


def _result_type(*items):
    return np.result_type(*(x.value if isinstance(x, Dual) else x for x in items))


def _tile(x, reps):
    reps = tuple(reps) if np.iterable(reps) else (reps,)
    value = np.tile(x.value, reps)
    reps = (1,) * (value.ndim - len(reps)) + reps
    return Dual(value, np.tile(_pad(x, value.ndim), (1,) + reps), x.lo)


def _ascontiguous(x, dtype=None, **kwargs):
    return Dual(np.ascontiguousarray(x.value), np.ascontiguousarray(x.tangents), x.lo)


_FUNCTIONS = {
    np.concatenate: _concatenate, np.stack: _stack, np.broadcast_to: _broadcast_to,
    np.broadcast_arrays: _broadcast_arrays, np.where: _where, np.sum: _sum, np.take: _take, np.dot: _dot,
    np.reshape: _reshape, np.swapaxes: _swapaxes, np.empty_like: _empty_like, np.zeros_like: _zeros_like,
    np.result_type: _result_type, np.tile: _tile, np.ascontiguousarray: _ascontiguous,
    np.ndim: lambda x: x.ndim, np.shape: lambda x: x.shape,
    np.size: lambda x, axis=None: np.size(x.value, axis),
    np.iscomplexobj: lambda x: False, np.real: lambda x: x.value, np.matmul: matmul,
}


def trimmed(x):
    """``x`` without the directions at either end of its range whose tangents are all 0 (a Dual computed with
    others may depend on fewer directions than they: the value of a jet of the motion depends on the motion's
    first orders only); anything else as it is.
    """
    if not isinstance(x, Dual) or not x.tangents.shape[0]:
        return x
    used = np.flatnonzero(np.any(x.tangents.reshape(x.tangents.shape[0], -1) != 0.0, axis=1))
    if used.size == x.tangents.shape[0]:
        return x
    lo, hi = (used[0], used[-1] + 1) if used.size else (0, 0)
    return Dual(x.value, x.tangents[lo:hi], x.lo + int(lo))


def empty(shape, *like) -> np.ndarray | Dual:
    """``np.empty(shape)`` of floats; a Dual over the directions of the Duals among ``like`` when it holds
    any.
    """
    if any(isinstance(x, Dual) for x in like):
        lo, hi = span(*like)
        return Dual(np.empty(shape), np.empty((hi - lo,) + tuple(shape)), lo)
    return np.empty(shape, np.result_type(*like, float))


def zeros(shape, *like) -> np.ndarray | Dual:
    """``np.zeros(shape)`` (as :func:`empty`)."""
    if any(isinstance(x, Dual) for x in like):
        lo, hi = span(*like)
        return Dual(np.zeros(shape), np.zeros((hi - lo,) + tuple(shape)), lo)
    return np.zeros(shape, np.result_type(*like, float))


# --- jets of Duals (fpr.model.jets: the value a real jet (K+1, ...), the tangents (n, K+1, ...)) ---------
_PAIRS = {}


def _pairs(K):
    """(k, n - k, W) over the pairs 0 <= k <= n <= K: W (K+1, pairs) C(n, k) where the pair is of order n."""
    found = _PAIRS.get(K)
    if found is None:
        pairs = [(n, k) for n in range(K + 1) for k in range(n + 1)]
        w = np.zeros((K + 1, len(pairs)))
        for i, (n, k) in enumerate(pairs):
            w[n, i] = math.comb(n, k)
        found = _PAIRS[K] = (np.array([k for n, k in pairs]), np.array([n - k for n, k in pairs]), w)
    return found


def jet_products(da, db, K):
    """The elementwise product of real jets da, db (orders >= K+1, ...), orders 0..K, in a few numpy calls:
    every term's product at once (da[k] * db[n - k] over the pairs k <= n <= K), weighted and summed per order
    n by one matrix product (the dual path's arrays are small: numpy's per-term calls cost more than the
    arithmetic).
    """
    ka, kb, w = _pairs(K)
    terms = da[ka] * db[kb]
    return np.dot(w, terms.reshape(terms.shape[0], -1)).reshape((K + 1,) + terms.shape[1:])


def jet_batch(x: Dual):
    """A jet Dual's tangents (n, K+1, ...) as a batch of jets (K+1, n, ...) (a view)."""
    return np.swapaxes(x.tangents, 0, 1)


def jet_leibniz(da, db, K):
    """The elementwise product of jets (orders >= K+1, ...) of which one or both are Duals, orders 0..K."""
    av, bv = _val(da), _val(db)
    parts = []
    if isinstance(da, Dual):
        parts.append((np.swapaxes(jet_products(jet_batch(da), bv[:K + 1, None], K), 0, 1), da.lo))
    if isinstance(db, Dual):
        parts.append((np.swapaxes(jet_products(av[:K + 1, None], jet_batch(db), K), 0, 1), db.lo))
    return gather(jet_products(av, bv, K), parts)


def jet_chain(value, parts):
    """The Dual jet of ``value`` (K+1, ...) (a real jet) whose tangents are the sum of the jet products of the
    Duals' tangents by real jets: ``parts`` [(Dual jet (orders >= K+1, ...), real jet (K+1, ...))] (a
    function's jet and its derivative's: d sin a = cos a da).
    """
    K, nd = value.shape[0] - 1, value.ndim
    out = []
    for x, m in parts:
        x = x.reshape(x.shape[:1] + (1,) * (nd - x.ndim) + x.shape[1:]) if nd > x.ndim else x
        m = m.reshape(m.shape[:1] + (1,) * (nd - m.ndim) + m.shape[1:]) if nd > m.ndim else m
        out.append((np.swapaxes(jet_products(jet_batch(x)[:K + 1], m[:K + 1, None], K), 0, 1), x.lo))
    return gather(value, out)


__all__ = ["Dual", "empty", "gather", "jet_batch", "jet_chain", "jet_leibniz", "jet_products", "lift", "span",
           "trimmed", "zeros"]
