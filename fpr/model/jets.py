"""Forward-mode "jets" of time derivatives, vectorised with numpy.

A :class:`Jet` carries a quantity together with its first ``K`` time derivatives,
``d[k] = x^(k)(t)``, stacked along a leading axis in front of any batch/tensor shape.
Arithmetic, elementary functions and batched linear algebra propagate every derivative
exactly (Leibniz rule and recurrences of Faa di Bruno type), so a motion s(t) given with
s', ..., s'''' yields e.g. the thrust F(t) with F', F'' without symbolic or numerical
differentiation. Loops run only over derivative orders; all samples go through numpy at once.

Example:
    >>> t = np.linspace(0.0, 1.0, 5)
    >>> s = Jet.from_derivatives([t**2, 2 * t, 2 + 0 * t])    # s = t^2 up to s''
    >>> phi = atan2(-s, 1.0)                                   # phi, phi', phi''
    >>> phi.order, phi.shape, float(phi.d[2][0])              # phi''(0) = -s''(0)
    (2, (5,), -2.0)
"""
import math

import numpy as np

from fpr import _native as native
from fpr.model.dual import Dual, empty, gather, jet_batch, jet_chain, jet_leibniz
from fpr.model.errors import ModelArgumentError

_MAXK = 16
_B = np.array([[math.comb(n, k) for k in range(_MAXK + 1)] for n in range(_MAXK + 1)], float)


def _kernel():
    """The native jet products and solves (:mod:`fpr._native`'s part ``jets``, ``fpr/_native/jets.c``), or None
    for numpy's (the reference the tests hold them equal to).
    """
    return native.use("jets")


def _suffix_batches(*batches):
    """(the broadcast batch shape, its size, each batch's size) when every batch shape with its leading 1s dropped
    is a suffix of the broadcast one (what ``fpr/_native/jets.c``'s ``s % S_a`` indexing broadcasts); else None.
    """
    try:
        out = np.broadcast_shapes(*batches)
    except ValueError:
        return None
    sizes = []
    for b in batches:
        b = tuple(b)
        while b and b[0] == 1:
            b = b[1:]
        if b and b != out[len(out) - len(b):]:
            return None
        sizes.append(math.prod(b))
    return out, math.prod(out), sizes


def _compiled_product(da, db, K):
    """:func:`_leibniz`'s matrix products natively (the part ``jets``): ``da`` (Ka+1, ..., n, m), ``db`` (Kb+1,
    ..., m, k) padded to one ndim, the result's orders 0..K (K <= Ka + Kb, terms beyond an operand's order are 0);
    None where it does not apply (no kernel, mixed or other dtypes, sizes beyond its limits, batches that broadcast
    otherwise).
    """
    if isinstance(da, Dual) or isinstance(db, Dual):
        return _dual_product(da, db, K)
    kernel = _kernel()
    if (kernel is None or da.dtype != db.dtype or da.dtype.char not in "dD" or K > _MAXK or da.ndim < 3
            or db.ndim < 3 or da.shape[-1] != db.shape[-2]):
        return None
    n, m, k = da.shape[-2], da.shape[-1], db.shape[-1]
    found = _suffix_batches(da.shape[1:-2], db.shape[1:-2])
    if found is None or found[1] == 0 or max(n, m, k) > 32:
        return None
    batch, size, (sa, sb) = found
    out = np.empty((K + 1,) + batch + (n, k), da.dtype)
    kernel.product(np.ascontiguousarray(da), np.ascontiguousarray(db), out, size, sa, sb, n, m, k)
    return out


def small_matmul(a, b):
    """``np.matmul(a, b)`` of batches of small matrices (..., n, m) @ (..., m, k), natively (the part ``jets``)
    where it applies (about 5 times faster than numpy's on the planner's batches of 4 x 4 matrices; round-off
    apart, the same).
    """
    if isinstance(a, Dual) or isinstance(b, Dual):
        return _dual_product(a[None], b[None], 0)[0]
    a, b = np.asarray(a), np.asarray(b)
    out = _compiled_product(a[None], b[None], 0) if a.ndim >= 2 and b.ndim >= 2 else None
    return np.matmul(a, b) if out is None else out[0]


def _pad(d, ndim):
    """Insert unit axes after the derivative axis so that ``d`` has ``ndim`` trailing dims."""
    extra = ndim - (d.ndim - 1)
    return d.reshape(d.shape[:1] + (1,) * extra + d.shape[1:]) if extra > 0 else d


def _ax(axis):
    """Map an axis of the trailing shape to an axis of ``d``."""
    return axis + 1 if axis >= 0 else axis


def _wsum(w, terms):
    """Weighted sum ``sum_i w[i] * terms[i]`` over the leading axis (one BLAS dot: what ``np.tensordot`` does,
    without its Python overhead, which dominated on small batches).
    """
    if isinstance(terms, Dual):
        t = terms.tangents
        if t.shape[1] == 0 or t.size == 0:
            return Dual(np.zeros(t.shape[2:]), np.zeros(t.shape[:1] + t.shape[2:]), terms.lo)
        tangents = np.matmul(w, t.reshape(t.shape[:2] + (-1,))).reshape(t.shape[:1] + t.shape[2:])
        return Dual(_wsum(w, terms.value), tangents, terms.lo)
    terms = np.asarray(terms)
    if terms.shape[0] == 0 or terms.size == 0:
        return np.tensordot(w, terms, axes=(0, 0))  # empty sums: tensordot's zeros of the right shape
    return np.dot(w, terms.reshape(terms.shape[0], -1)).reshape(terms.shape[1:])


def _parts(x):
    """Return ``(d, order)`` of a Jet, or ``(x[None], None)`` for a constant (infinite order)."""
    if isinstance(x, Jet):
        return x.d, x.order
    return (x if isinstance(x, Dual) else np.asarray(x))[None], None


def _lift(x, order):
    """Return ``x`` if it is a Jet, else the constant Jet of ``x`` with the given order."""
    return x if isinstance(x, Jet) else Jet.constant(x, order)


def inexact(x) -> np.ndarray:
    """``x`` as an array of floats, complex values kept (complex-step differentiation
    passes through every function of this package that converts its inputs this way).
    """
    if isinstance(x, Dual):
        return x
    x = np.asarray(x)
    return x if x.dtype.kind in "fc" else x.astype(float)  # inexact (np.issubdtype, cheaper)


def _small_solve(a, b=None):
    """``np.linalg.solve(a, b)`` (``b`` None: ``np.linalg.inv(a)``) of a real batch a (..., n, n), b (..., n, k),
    n, k <= 32, natively by Gauss-Jordan elimination (the part ``jets``; about 3 times faster than numpy's on
    batches of 4 x 4 matrices, the same to round-off); numpy's for other batches and singular matrices (which numpy
    then reports as it does).
    """
    kernel = _kernel()
    numpy_s = (lambda: np.linalg.inv(a)) if b is None else (lambda: np.linalg.solve(a, b))
    if kernel is None or a.dtype.char != "d" or a.ndim < 2 or not 1 <= a.shape[-1] <= 32 or a.size == 0:
        return numpy_s()
    if b is not None:
        if (b.dtype.char != "d" or b.ndim != a.ndim or b.shape[:-1] != a.shape[:-1] or not 1 <= b.shape[-1] <= 32):
            return numpy_s()
        b = np.ascontiguousarray(b)
    out = np.empty(a.shape if b is None else b.shape)
    n = a.shape[-1]
    if not kernel.gauss_jordan(np.ascontiguousarray(a), b, out, a.size // (n * n), n, out.shape[-1]):
        return numpy_s()
    return out


def inverse(a):
    """``np.linalg.inv`` of a batch of matrices (..., n, n) (Duals: d(A^-1) = -A^-1 dA A^-1)."""
    if isinstance(a, Dual):
        r = _small_solve(a.value)
        return Dual(r, -small_matmul(small_matmul(r, a.tangents), r), a.lo)
    return _small_solve(a)


def solve_matrices(a, b):
    """``np.linalg.solve(a, b)`` for a batch of matrices a (..., n, n) and right-hand sides b (..., n, k)."""
    if isinstance(a, Dual) or isinstance(b, Dual):
        return _dual_solve_matrices(a, b)
    return _small_solve(a, b) if np.ndim(b) == np.ndim(a) else np.linalg.solve(a, b)


def _atan2_value(y, x):
    """``arctan2`` that also takes complex-step arguments ``a + i h b`` (h tiny): the real part is
    the angle of the real parts, the imaginary part its first-order change (exact for h -> 0).
    """
    if not (np.iscomplexobj(y) or np.iscomplexobj(x)):
        return np.arctan2(y, x)
    yr, xr = np.real(y), np.real(x)
    return np.arctan2(yr, xr) + 1j * (xr * np.imag(y) - yr * np.imag(x)) / (xr * xr + yr * yr)


def sin_cos_value(a):
    """``(np.sin(a), np.cos(a))`` of an array; for complex-step arguments ``a = x + i h b`` (h tiny) from the
    real sine and cosine: sin(x) + i cos(x) h b and cos(x) - i sin(x) h b, which is what numpy's complex sine
    and cosine give there bit for bit (cosh(h b) = 1, sinh(h b) = h b in floating point), at a fraction of
    their cost (no complex transcendental functions).
    """
    if isinstance(a, Dual):
        s, c = np.sin(a.value), np.cos(a.value)
        return Dual(s, a.tangents * c, a.lo), Dual(c, a.tangents * -s, a.lo)
    if not np.iscomplexobj(a):
        return np.sin(a), np.cos(a)
    x, b = a.real, a.imag
    s, c = np.sin(x), np.cos(x)
    sin, cos = np.empty(a.shape, a.dtype), np.empty(a.shape, a.dtype)
    sin.real, sin.imag = s, c * b
    cos.real, cos.imag = c, -(s * b)
    return sin, cos


def _leibniz(da, db, K, op=np.multiply):
    """Derivatives of ``op(a, b)`` for a bilinear ``op``: sum_k C(n,k) op(a^(k), b^(n-k)).

    Elementwise products (the usual case) accumulate term by term into one preallocated array (no stacked
    temporaries: the planner's complex-step batches are large); other ``op`` stack and weight.
    """
    out = _compiled_product(da[:K + 1], db[:K + 1], K) if op is np.matmul else None
    if out is not None:
        return out
    if op is not np.multiply:
        return np.stack([_wsum(_B[n, :n + 1], op(da[:n + 1], db[n::-1])) for n in range(K + 1)])
    if isinstance(da, Dual) or isinstance(db, Dual):
        return jet_leibniz(da, db, K)
    out = np.empty((K + 1,) + np.broadcast_shapes(da.shape[1:], db.shape[1:]), np.result_type(da, db))
    tmp = np.empty(out.shape[1:], out.dtype) if K else None
    for n in range(K + 1):
        np.multiply(da[0], db[n], out=out[n])
        for k in range(1, n + 1):
            np.multiply(da[k], db[n - k], out=tmp)
            if _B[n, k] != 1:
                tmp *= _B[n, k]
            out[n] += tmp
    return out


def _add_const(d, c):
    """Add the constant ``c`` to the value ``d[0]`` only."""
    out = empty(d.shape[:1] + np.broadcast_shapes(d.shape[1:], c.shape), d, c)
    out[...] = d
    out[0] += c
    return out


class Jet:
    """A quantity and its time derivatives.

    Args:
        d: Array ``(K+1, *shape)``, ``d[k]`` the k-th derivative; ``shape`` is batch dims first,
            then vector/matrix dims (e.g. ``(N,)``, ``(N, 2)``, ``(N, 4, 4)``).
    """

    __array_ufunc__ = None  # ``ndarray <op> Jet`` defers to the Jet's reflected operator.

    def __init__(self, d):
        d = d if isinstance(d, Dual) else np.asarray(d)
        if d.ndim == 0 or not 1 <= d.shape[0] <= _MAXK + 1:
            raise ModelArgumentError("d", d.shape, f"Jet needs 1..{_MAXK + 1} derivatives along axis 0, got an "
                                                   f"array of shape {d.shape}")
        self.d = d if d.dtype.kind in "fc" else d.astype(float)  # inexact (np.issubdtype, cheaper)

    @classmethod
    def constant(cls, x, order):
        """Jet of a time-constant value ``x`` (all derivatives zero)."""
        x = np.asarray(x)
        d = np.zeros((order + 1,) + x.shape, np.result_type(x, float))
        d[0] = x
        return cls(d)

    @classmethod
    def from_derivatives(cls, derivs):
        """Jet from the list ``[x, x', ..., x^(K)]`` (arrays broadcast to a common shape)."""
        return cls(np.stack(np.broadcast_arrays(*[np.asarray(x) for x in derivs])))

    @classmethod
    def variable(cls, t, order):
        """Jet of the independent variable itself: ``[t, 1, 0, ..., 0]``."""
        j = cls.constant(np.asarray(t, float), order)
        if order >= 1:
            j.d[1] = 1.0
        return j

    order = property(lambda self: self.d.shape[0] - 1, doc="Highest derivative order K.")
    shape = property(lambda self: self.d.shape[1:], doc="Trailing (batch + tensor) shape.")
    ndim = property(lambda self: self.d.ndim - 1, doc="Number of trailing dims.")
    value = property(lambda self: self.d[0], doc="The undifferentiated value ``d[0]``.")
    mT = property(lambda self: Jet(np.swapaxes(self.d, -1, -2)), doc="Swap the last two dims.")
    T = mT  # Batch-first convention: only the last two (matrix) dims are transposed.

    def __repr__(self):
        return f"Jet(order={self.order}, shape={self.shape})"

    def __getitem__(self, key):
        return Jet(self.d[(slice(None),) + (key if isinstance(key, tuple) else (key,))])

    def truncate(self, order):
        """Keep derivatives ``0..order`` only (the result shares :meth:`shared_cache`)."""
        if not 0 <= order <= self.order:
            raise ModelArgumentError("order", order, f"cannot truncate a Jet of order {self.order} to order {order}: "
                                                     f"give 0 <= order <= {self.order}")
        out = Jet(self.d[:order + 1])
        out._shared = self.shared_cache()
        return out

    def shared_cache(self) -> dict:
        """A dict shared by this Jet and its truncations, for results computed from it that several
        callers need (e.g. the sines and cosines of a chain's angles, :mod:`fpr.model.planar`). A cached
        Jet result may be of a higher order than the caller's: derivatives 0..k of a jet function depend
        on derivatives 0..k of its argument only, so the caller truncates it. Do not modify ``d`` in place
        once the cache is used.
        """
        cache = getattr(self, "_shared", None)
        if cache is None:
            cache = self._shared = {}
        return cache

    def derivative(self):
        """The Jet of ``x'`` (order K-1): derivatives shifted down by one."""
        return Jet(self.d[1:])

    def reshape(self, *shape):
        """Reshape the trailing dims."""
        shape = shape[0] if len(shape) == 1 and isinstance(shape[0], tuple) else shape
        return Jet(self.d.reshape((self.d.shape[0],) + tuple(shape)))

    def sum(self, axis=None):
        """Sum over trailing ``axis`` (int or tuple; ``None`` for all trailing dims)."""
        if axis is None:
            axis = tuple(range(self.ndim))
        axis = tuple(map(_ax, axis)) if isinstance(axis, tuple) else _ax(axis)
        return Jet(self.d.sum(axis=axis))

    # --- arithmetic -------------------------------------------------------------------------
    def _binary(self, other, jet_op, const_op):
        if isinstance(other, Jet):
            K, nd = min(self.order, other.order), max(self.ndim, other.ndim)
            return Jet(jet_op(_pad(self.d[:K + 1], nd), _pad(other.d[:K + 1], nd), K))
        c = other if isinstance(other, Dual) else np.asarray(other)
        return Jet(const_op(_pad(self.d, c.ndim), c))

    def __add__(self, other):
        return self._binary(other, lambda a, b, K: a + b, _add_const)

    __radd__ = __add__

    def __neg__(self):
        return Jet(-self.d)

    def __sub__(self, other):
        return self + (-(other if isinstance(other, (Jet, Dual)) else np.asarray(other)))

    def __rsub__(self, other):
        return (-self) + other

    def __mul__(self, other):
        return self._binary(other, _leibniz, lambda d, c: d * c)

    __rmul__ = __mul__

    def __truediv__(self, other):
        return self._binary(other, _divide, lambda d, c: d / c)

    def __rtruediv__(self, other):
        return _lift(other, self.order) / self

    def __matmul__(self, other):
        return matmul(self, other)

    def __rmatmul__(self, other):
        return matmul(other, self)

    def __pow__(self, p):
        """Small integer powers by repeated products; real powers by ``a f' = p a' f`` (a != 0)."""
        if isinstance(p, (int, np.integer)):
            if p < 0:
                return 1.0 / self ** (-p)
            result = self if p else Jet.constant(np.ones(self.shape, self.d.dtype), self.order)
            for _ in range(p - 1):
                result = result * self
            return result
        a, f = self.d, np.empty_like(self.d)
        f[0] = a[0] ** p
        for n in range(1, self.order + 1):
            f[n] = (p * _wsum(_B[n - 1, :n], a[1:n + 1] * f[n - 1::-1])
                    - _wsum(_B[n - 1, 1:n], a[1:n] * f[n - 1:0:-1])) / a[0]
        return Jet(f)


def _divide(da, db, K):
    """Quotient recurrence q^(n) = (a^(n) - sum_{k=1..n} C(n,k) b^(k) q^(n-k)) / b."""
    if isinstance(da, Dual) or isinstance(db, Dual):  # dq = (da - q db) / b (jet products with real jets)
        bv = _value(db)
        q, r = _divide(_value(da), bv, K), _reciprocal(bv[:K + 1])
        parts = [(da, r)] if isinstance(da, Dual) else []
        if isinstance(db, Dual):
            parts.append((db, -_leibniz(q, r, K)))
        return jet_chain(q, parts)
    q = empty((K + 1,) + np.broadcast_shapes(da.shape[1:], db.shape[1:]), da, db)
    for n in range(K + 1):
        acc = da[n] - _wsum(_B[n, 1:n + 1], db[1:n + 1] * q[n - 1::-1]) if n else da[0]
        q[n] = acc / db[0]
    return q


def _integrate(value, dj):
    """Jet with value ``value`` whose derivative is the Jet ``dj``."""
    return Jet(np.concatenate([np.broadcast_to(value, dj.shape)[None], dj.d]))


# --- elementwise functions ---------------------------------------------------------------------
def sincos(a):
    """Return ``(sin(a), cos(a))`` by the coupled recurrence
    s^(n) = sum_{k<n} C(n-1,k) c^(k) a^(n-k),  c^(n) = -sum_{k<n} C(n-1,k) s^(k) a^(n-k).
    """
    if not isinstance(a, Jet):
        return sin_cos_value(np.asarray(a)) if np.iscomplexobj(a) else (np.sin(a), np.cos(a))
    if isinstance(a.d, Dual):  # the real jets, and d sin = cos da, d cos = -sin da (jet products)
        s, c = sincos(Jet(a.d.value))
        return Jet(jet_chain(s.d, [(a.d, c.d)])), Jet(jet_chain(c.d, [(a.d, -s.d)]))
    d, s, c = a.d, np.empty_like(a.d), np.empty_like(a.d)
    s[0], c[0] = sin_cos_value(d[0])
    for n in range(1, a.order + 1):
        w, dn = _B[n - 1, :n], d[n:0:-1]
        s[n], c[n] = _wsum(w, c[:n] * dn), -_wsum(w, s[:n] * dn)
    return Jet(s), Jet(c)


def sin(a):
    """Sine (see :func:`sincos`)."""
    return sincos(a)[0]


def cos(a):
    """Cosine (see :func:`sincos`)."""
    return sincos(a)[1]


def exp(a):
    """Exponential: f^(n) = sum_{k<n} C(n-1,k) f^(k) a^(n-k)."""
    if not isinstance(a, Jet):
        return np.exp(a)
    d, f = a.d, np.empty_like(a.d)
    f[0] = np.exp(d[0])
    for n in range(1, a.order + 1):
        f[n] = _wsum(_B[n - 1, :n], f[:n] * d[n:0:-1])
    return Jet(f)


def log(a):
    """Natural logarithm, from the derivative (log a)' = a' / a."""
    if not isinstance(a, Jet):
        return np.log(a)
    if a.order == 0:
        return Jet(np.log(a.d))
    return _integrate(np.log(a.value), a.derivative() / a.truncate(a.order - 1))


def sqrt(a):
    """Square root: f^(n) = (a^(n) - sum_{k=1}^{n-1} C(n,k) f^(k) f^(n-k)) / (2 f); needs a > 0."""
    if not isinstance(a, Jet):
        return np.sqrt(a)
    if isinstance(a.d, Dual):  # d sqrt(a) = da / (2 sqrt(a)) (jet product with the real jet 1 / (2 f))
        f = sqrt(Jet(a.d.value)).d
        return Jet(jet_chain(f, [(a.d, _reciprocal(2.0 * f))]))
    d, f = a.d, np.empty_like(a.d)
    f[0] = np.sqrt(d[0])
    for n in range(1, a.order + 1):
        f[n] = (d[n] - _wsum(_B[n, 1:n], f[1:n] * f[n - 1:0:-1])) / (2 * f[0])
    return Jet(f)


def square(a):
    """``a * a``."""
    return a * a


def atan2(y, x):
    """Four-quadrant angle with continuous derivatives across the branch cut:
    value ``np.arctan2(y, x)``, derivative jet ``(x y' - y x') / (x^2 + y^2)``.
    """
    if not isinstance(y, Jet) and not isinstance(x, Jet):
        return _atan2_value(y, x)
    K = min(j.order for j in (y, x) if isinstance(j, Jet))
    y, x = _lift(y, K).truncate(K), _lift(x, K).truncate(K)
    if K and (isinstance(y.d, Dual) or isinstance(x.d, Dual)):  # d angle = (x dy - y dx) / (x^2 + y^2)
        yv, xv = _value(y.d), _value(x.d)
        r = _reciprocal(_leibniz(xv, xv, K) + _leibniz(yv, yv, K))
        u, v = _leibniz(xv, r, K), _leibniz(yv, r, K)  # the angle's derivative: u y' - v x'
        angle = np.concatenate([_atan2_value(yv[0], xv[0])[None],
                                _leibniz(u, yv[1:], K - 1) - _leibniz(v, xv[1:], K - 1)])
        parts = [(y.d, u)] if isinstance(y.d, Dual) else []
        if isinstance(x.d, Dual):
            parts.append((x.d, -v))
        return Jet(jet_chain(angle, parts))
    value = _atan2_value(y.value, x.value)
    if K == 0:
        return Jet(value[None])
    y0, x0 = y.truncate(K - 1), x.truncate(K - 1)
    return _integrate(value, (x0 * y.derivative() - y0 * x.derivative()) / (x0 * x0 + y0 * y0))


def hypot(x, y):
    """``sqrt(x^2 + y^2)`` (not differentiable where it vanishes)."""
    return sqrt(x * x + y * y)


def dot(a, b, axis=-1):
    """Inner product of ``a`` and ``b`` along trailing ``axis``."""
    p = a * b
    return p.sum(axis) if isinstance(p, Jet) else np.sum(p, axis=axis)


def norm(v, axis=-1):
    """Euclidean norm along trailing ``axis``."""
    return sqrt(dot(v, v, axis))


# --- linear algebra on the trailing dims ---------------------------------------------------------
def matmul(a, b):
    """Batched ``a @ b`` with numpy's matmul semantics on the trailing dims (1-D = vector)."""
    if not isinstance(a, Jet) and not isinstance(b, Jet):
        return np.matmul(a, b)
    (da, ka), (db, kb) = _parts(a), _parts(b)
    va, vb = da.ndim == 2, db.ndim == 2
    da, db = (da[:, None, :] if va else da), (db[..., None] if vb else db)
    nd = max(da.ndim, db.ndim) - 1
    da, db = _pad(da, nd), _pad(db, nd)
    if ka is None or kb is None:  # a constant: the Leibniz sum of its single (order 0) term
        d = _jet_product(da[:1], db, kb) if ka is None else _jet_product(da, db[:1], ka)
    else:
        d = _leibniz(da, db, min(ka, kb), np.matmul)
    d = d[..., 0] if vb else d
    return Jet(d[..., 0, :] if va else d)


def matvec(A, x):
    """Batched matrix-vector product: ``A`` (..., n, m), ``x`` (..., m) -> (..., n)."""
    return matmul(A, x[..., None])[..., 0]


def solve(A, b):
    """Solve ``A x = b`` for batched square ``A`` (..., n, n).

    ``b`` is a stack of vectors (..., n) if it has one dim less than ``A`` or cannot be a stack
    of (n, m) matrices (e.g. ``A`` (n, n), ``b`` (N, n) with N != n), else of matrices.
    ``A0`` is inverted once and x^(n) = A0^{-1} (b^(n) - sum_{k=1..n} C(n,k) A^(k) x^(n-k)).
    Either argument may be a constant array.
    """
    (dA, kA), (dB, kB) = _parts(A), _parts(b)
    size = dA.shape[-1]
    vec = dB.shape[-1] == size and (dB.ndim in (2, dA.ndim - 1) or dB.shape[-2] != size)
    dB = dB[..., None] if vec else dB
    nd = max(dA.ndim, dB.ndim) - 1
    dA, dB = _pad(dA, nd), _pad(dB, nd)
    K = min([k for k in (kA, kB) if k is not None], default=0)
    if isinstance(dA, Dual) or isinstance(dB, Dual):
        x = _dual_jet_solve(dA, kA, dB, K)
    else:
        x = _jet_solve(inverse(dA[0]), dA if kA is not None else None, dB, K)
    x = Jet(x[..., 0] if vec else x)
    return x if isinstance(A, Jet) or isinstance(b, Jet) else x.value


def _jet_solve(inv, dA, dB, K):
    """The jet of A^-1 b, orders 0..K, from inv = A0^-1, A's jet dA (None: a constant A) and b's dB
    (:func:`solve`).
    """
    x = _compiled_solve(inv, dA, dB, K)
    if x is None and dA is None:
        x = np.matmul(inv, dB[:K + 1])
    elif x is None:
        xs = [np.matmul(inv, dB[0])]
        for n in range(1, K + 1):
            r = _wsum(_B[n, 1:n + 1], np.matmul(dA[1:n + 1], np.stack(xs[::-1])))
            xs.append(np.matmul(inv, (dB[n] if n < dB.shape[0] else 0.0) - r))
        x = np.stack(xs)
    return x


# --- Dual numbers (fpr.model.dual) through the jets: the value by the real code, the tangents as a batch ---
def _value(x):
    return x.value if isinstance(x, Dual) else x


def _jet_product(da, db, K):
    """The jet of the matrix product of jets da (Ka+1, ..., n, m), db (Kb+1, ..., m, k), orders 0..K (terms
    beyond an operand's order 0).
    """
    out = _compiled_product(da, db, K)
    if out is not None:
        return out
    return np.stack([sum(_B[n, k] * np.matmul(da[k], db[n - k]) for k in range(max(0, n - len(db) + 1),
                                                                             min(n, len(da) - 1) + 1))
                     for n in range(K + 1)])


def _dual_product(da, db, K):
    """:func:`_compiled_product` of jets of which one or both are Duals: d(AB) = dA B + A dB."""
    av, bv = _value(da), _value(db)
    parts = []
    if isinstance(da, Dual):
        parts.append((np.swapaxes(_jet_product(jet_batch(da), bv[:, None], K), 0, 1), da.lo))
    if isinstance(db, Dual):
        parts.append((np.swapaxes(_jet_product(av[:, None], jet_batch(db), K), 0, 1), db.lo))
    return gather(_jet_product(av, bv, K), parts)


def _reciprocal(db):
    """The real jet of 1 / b from b's ``db`` (K+1, ...)."""
    one = np.zeros(db.shape)
    one[0] = 1.0
    return _divide(one, db, db.shape[0] - 1)


def _dual_jet_solve(dA, kA, dB, K):
    """:func:`solve`'s jet of A^-1 b when A's or b's jet is a Dual: x by the real solve, its tangents from
    A0^-1 (once) as the jet solve of A dx = db - dA x.
    """
    av, bv = _value(dA), _value(dB)
    inv = _small_solve(av[0])
    x = _jet_solve(inv, av if kA is not None else None, bv, K)
    parts = []
    if isinstance(dB, Dual):
        db = dB.tangents[:, :K + 1]
        if db.shape[1] < K + 1:  # b's orders beyond its own are 0
            db = np.concatenate([db, np.zeros(db.shape[:1] + (K + 1 - db.shape[1],) + db.shape[2:])], axis=1)
        parts.append((db, dB.lo))
    if isinstance(dA, Dual):
        parts.append((-np.swapaxes(_jet_product(jet_batch(dA), x[:, None], K), 0, 1), dA.lo))
    rhs = gather(x, parts)
    t = _jet_solve(inv[None], av[:K + 1, None] if kA is not None else None, jet_batch(rhs), K)
    return Dual(x, np.swapaxes(t, 0, 1), rhs.lo)


def _dual_solve_matrices(a, b):
    """:func:`solve_matrices` of Duals: x = A^-1 b by one real inverse, dx = A^-1 (db - dA x)."""
    inv = _small_solve(_value(a))
    x = small_matmul(inv, _value(b))
    parts = [(b.tangents, b.lo)] if isinstance(b, Dual) else []
    if isinstance(a, Dual):
        parts.append((-small_matmul(a.tangents, x), a.lo))
    rhs = gather(x, parts)
    return Dual(x, small_matmul(inv, rhs.tangents), rhs.lo)


def _compiled_solve(inv, dA, dB, K):
    """The jet of A^-1 b, orders 0..K, natively (the part ``jets``: :func:`solve`'s recurrence) from ``inv`` =
    A0^-1 (..., n, n), A's jet ``dA`` (or None: a constant A) and b's ``dB`` (Kb+1, ..., n, k) (orders beyond Kb
    are 0); None where it does not apply (as :func:`_compiled_product`).
    """
    kernel = _kernel()
    dA = inv[None] if dA is None else dA[:K + 1]
    dB = dB[:K + 1]
    if (kernel is None or not inv.dtype == dA.dtype == dB.dtype or inv.dtype.char not in "dD" or K > _MAXK
            or dB.ndim < 3 or inv.shape[-1] != dB.shape[-2] or max(inv.shape[-1], dB.shape[-1]) > 32):
        return None
    found = _suffix_batches(inv.shape[:-2], dA.shape[1:-2], dB.shape[1:-2])
    if found is None or found[1] == 0:
        return None
    batch, size, (si, sa, sb) = found
    n, k = inv.shape[-1], dB.shape[-1]
    out = np.empty((K + 1,) + batch + (n, k), inv.dtype)
    kernel.solve(np.ascontiguousarray(inv), np.ascontiguousarray(dA), np.ascontiguousarray(dB), out, size, si, sa,
                 sb, n, k)
    return out


def _align_all(items):
    """Lift constants, truncate to the common order, pad to common trailing ndim."""
    K = min(x.order for x in items if isinstance(x, Jet))
    ds = [_lift(x, K).d[:K + 1] for x in items]
    nd = max(d.ndim for d in ds) - 1
    return [_pad(d, nd) for d in ds]


def stack(items, axis=0):
    """Stack Jets (and constants, broadcast) along a new trailing ``axis``."""
    return Jet(np.stack(np.broadcast_arrays(*_align_all(items)), axis=_ax(axis)))


def concatenate(items, axis=0):
    """Concatenate Jets (and constant arrays) along an existing trailing ``axis``."""
    return Jet(np.concatenate(_align_all(items), axis=_ax(axis)))
