r"""All the points of a planar chain at once: one table of sines and cosines, dynamics as matrix products.

Every point of the chain (:class:`fpr.model.planar.PlanarPoint`) is p(q) = S q + sum_k Rot(a_k.q + b_k) v_k.
The points of one robot share few distinct angles theta_a = a_a.q + b_a (a link's angle appears in every
point beyond it). With Rot(theta) v = cos(theta) v + sin(theta) v_perp, v_perp = (-v_z, v_y), every point,
its Jacobian and its velocity product are *linear* in the features

.. math:: \varphi(q) = [1, \cos\theta_1 \dots \cos\theta_A, \sin\theta_1 \dots \sin\theta_A]:

    J_i(q) = \sum_f \varphi_f Y_{if}, \qquad
    \dot J_i \dot q = -\sum_a \omega_a^2 (\cos\theta_a v_{ia} + \sin\theta_a v_{ia\perp}),\
    \omega_a = a_a.\dot q,

with constant Y. The mass matrix and the bias of the bodies are then quadratic forms in the features:

.. math::
    M = \sum_{f \le f'} \varphi_f \varphi_{f'} K_{ff'}, \qquad
    c = \sum_{f, e} \varphi_f \psi_e L_{fe} + \sum_f \varphi_f L^g_f,\quad
    \psi = [\cos\theta_a \omega_a^2, \sin\theta_a \omega_a^2],

K, L and L^g (gravity's) summed over the bodies once (the bodies' rotational inertia I_b a_b a_b^T is in
K_00; only the products of features that meet a body are formed). A batch of samples is then one sine-cosine
table and a few matrix products (BLAS) instead of a loop over bodies and angles: what the planner's
derivatives (every sample with its tangents) spend their time on. Along a motion
(:mod:`fpr.model.jets`) the same products take jets.

The per-point formulation (:class:`~fpr.model.planar.PlanarPoint`) stays as the reference; the tests hold
this one equal to it (and to Pinocchio's CRBA / RNEA) to round-off.
"""

from __future__ import annotations

import numpy as np

from fpr.model import jets
from fpr.model.dual import Dual
from fpr.model.jets import Jet


class _Linear:
    """x -> x @ K + k0 on the last axis for a constant K (and constant k0). Takes arrays, Duals and Jets (k0 on
    the value).
    """

    def __init__(self, k, k0=None):
        self.k = np.ascontiguousarray(k, dtype=float)
        self.k0 = np.zeros(self.k.shape[1]) if k0 is None else np.asarray(k0, dtype=float).reshape(-1)
        self.size = self.k.shape[1]

    def __call__(self, x):
        d = x.d if isinstance(x, Jet) else x
        if isinstance(d, Dual):  # the value and the tangents by K, each one real product
            t = d.tangents
            tangents = (t.reshape(-1, t.shape[-1]) @ self.k).reshape(t.shape[:-1] + (-1,))
            out = Dual(d.value @ self.k, tangents, d.lo)
        else:
            out = d @ self.k
        value = out.value if isinstance(out, Dual) else out  # (a constant added: the tangents as they are)
        if isinstance(x, Jet):
            value[0] += self.k0
            return Jet(out)
        value += self.k0
        return out


class StackedPoints:
    """Points of a planar chain evaluated together from their features (module docstring).

    Args:
        points: the :class:`~fpr.model.planar.PlanarPoint` s, all over the same n coordinates.
        groups: names of consecutive runs of the points, {name: slice}, whose Jacobians and positions are asked
            for together (default: one group "all").

    Attributes:
        rows, offsets: the distinct angles a_a (A, n), b_a (A,).
        jacobian_map: Y, shape (F, P, 2, n), F = 1 + 2 A features.
        position_map: the points' rotated parts from [cos, sin], shape (2 A, P, 2).
        selectors: S of each point, shape (P, 2, n).
    """

    def __init__(self, points, groups=None):
        points = list(points)
        n = points[0].selector.shape[1]
        index, rows, offsets = {}, [], []
        for p in points:
            for r, o in zip(p.rows, p.offsets, strict=True):
                key = (np.asarray(r, float).tobytes(), float(o))
                if key not in index:
                    index[key] = len(rows)
                    rows.append(np.asarray(r, float))
                    offsets.append(float(o))
        a = len(rows)
        self.rows = np.array(rows, dtype=float).reshape(a, n)
        self.offsets = np.array(offsets, dtype=float)
        vectors = np.zeros((len(points), a, 2))
        for i, p in enumerate(points):
            for r, o, v in zip(p.rows, p.offsets, p.vectors, strict=True):
                vectors[i, index[(np.asarray(r, float).tobytes(), float(o))]] += v
        perp = np.stack([-vectors[..., 1], vectors[..., 0]], axis=-1)  # Rot(pi/2) v
        self.selectors = np.array([p.selector for p in points], dtype=float)
        self.position_map = np.concatenate([vectors.transpose(1, 0, 2), perp.transpose(1, 0, 2)])  # (2A, P, 2)
        # d/dtheta Rot(theta) v = cos(theta) v_perp - sin(theta) v
        y = np.zeros((1 + 2 * a, len(points), 2, n))
        y[0] = self.selectors
        y[1:1 + a] = perp.transpose(1, 0, 2)[..., None] * self.rows[:, None, None, :]
        y[1 + a:] = -vectors.transpose(1, 0, 2)[..., None] * self.rows[:, None, None, :]
        self.jacobian_map = y
        self.n, self.n_angles, self.n_points = n, a, len(points)
        self.groups = dict(groups or {"all": slice(0, len(points))})
        # per group: Jacobians from the features; positions from [features, q] (the selector on q)
        self._jacobians = {g: _Linear(y[:, sl].reshape(y.shape[0], -1)) for g, sl in self.groups.items()}
        self._positions = {g: _Linear(np.concatenate([np.zeros((1, 2 * (sl.stop - sl.start))),
                                                      self.position_map[:, sl].reshape(2 * a, -1),
                                                      self.selectors[sl].transpose(2, 0, 1).reshape(n, -1)]))
                           for g, sl in self.groups.items()}

    @property
    def n_features(self) -> int:
        """F = 1 + 2 A."""
        return 1 + 2 * self.n_angles

    def angles(self, q):
        """theta_a = a_a.q + b_a, shape (..., A)."""
        return jets.inexact(q) @ self.rows.T + self.offsets

    def features(self, q) -> np.ndarray:
        """[1, cos theta, sin theta], shape (..., F)."""
        sin, cos = jets.sin_cos_value(self.angles(q))
        return np.concatenate([np.ones(sin.shape[:-1] + (1,), sin.dtype), cos, sin], axis=-1)

    def features_jet(self, q: Jet) -> Jet:
        """The features along a motion (same order as q), kept in ``q.shared_cache()``: the bodies' dynamics and
        the hinges' Jacobian of one motion use the same ones.
        """
        cache, key = q.shared_cache(), ("stacked-features", id(self))
        owner, hit = cache.get(key, (None, None))
        if owner is not self or hit.order < q.order:
            d = q.d @ self.rows.T
            d[0] = d[0] + self.offsets
            sin, cos = jets.sincos(Jet(d))
            one = np.zeros(sin.d.shape[:-1] + (1,), sin.d.dtype)
            one[0] = 1.0
            hit = Jet(np.concatenate([one, cos.d, sin.d], axis=-1))
            cache[key] = (self, hit)
        return hit if hit.order == q.order else hit.truncate(q.order)

    def jacobians_from(self, features, group: str = "all"):
        """The Jacobians of a group's points from the features (..., F) (array or Jet): shape (..., P_g, 2, n)."""
        out = self._jacobians[group](features)
        return out.reshape(features.shape[:-1] + (-1, 2, self.n))

    def jacobians(self, q, group: str = "all") -> np.ndarray:
        """The Jacobians dp_i/dq of a group's points, shape (..., P_g, 2, n)."""
        return self.jacobians_from(self.features(q), group)

    def positions_from(self, q, features, group: str = "all"):
        """The positions of a group's points from q and its features (arrays, or Jets of one order): shape
        (..., P_g, 2).
        """
        if isinstance(features, Jet):
            both = Jet(np.concatenate([features.d, jets.inexact(q.d)], axis=-1))
        else:
            both = np.concatenate([features, np.broadcast_to(jets.inexact(q), features.shape[:-1] + (self.n,))],
                                  axis=-1)
        out = self._positions[group](both)
        return out.reshape(features.shape[:-1] + (-1, 2))


def _take(x, index):
    """``x[..., index]`` for an integer array ``index`` (array or Jet): np.take, about 3 times faster than
    fancy indexing on the last axis of large batches (the same values).
    """
    return Jet(np.take(x.d, index, axis=-1)) if isinstance(x, Jet) else np.take(x, index, axis=-1)


def _pairs(f: int):
    """The index pairs f <= f' of F features (upper triangle, row by row)."""
    return np.triu_indices(f)


class StackedDynamics:
    """Mass matrix and bias of a :class:`~fpr.model.planar.PlanarModel`'s bodies as products of features.

    The stacked points are the bodies' centres of mass, then the model's drone centres (group "centres") and
    hinges (group "hinges") of :class:`StackedPoints`.

    Args:
        model: the :class:`~fpr.model.planar.PlanarModel`.
    """

    def __init__(self, model):
        bodies = model.bodies
        nb, nd, nh = len(bodies), len(model.drone_centres), len(model.hinges)
        self.points = StackedPoints([b.com for b in bodies] + list(model.drone_centres) + list(model.hinges),
                                    {"bodies": slice(0, nb), "centres": slice(nb, nb + nd),
                                     "hinges": slice(nb + nd, nb + nd + nh)})
        n, y = model.n, self.points.jacobian_map[:, :nb]  # (F, B, 2, n)
        mass = np.array([b.mass for b in bodies])
        f = self.points.n_features
        # K_ff' = sum_b m_b Y_bf^T Y_bf' (+ the transposed pair off the diagonal), inertias in K_00
        full = np.einsum("b,fbin,gbim->fgnm", mass, y, y)
        full[0, 0] += sum(b.inertia * np.outer(b.angle_row, b.angle_row) for b in bodies)
        i, j = _pairs(f)
        k = full[i, j]
        off = i != j
        k[off] += full[j[off], i[off]]
        k = k.reshape(len(i), n * n)
        # most products of features meet no body (K is sparse): only those that do are formed; the constant
        # pair (1 * 1, the first) is the constant part of M
        keep = np.flatnonzero(np.any(k != 0, axis=1) & ((i != 0) | (j != 0)))
        self._pair_i, self._pair_j = i[keep], j[keep]
        self._mass = _Linear(k[keep], k[0])
        # L_fe = sum_b m_b Y_bf^T z_be with z = -(position map) (the velocity product); gravity: -Y^T g
        z = -self.points.position_map[:, :nb]  # (2A, B, 2)
        lfe = np.einsum("b,fbin,ebi->fen", mass, y, z)
        self._bias_f, self._bias_e = np.nonzero(np.any(lfe != 0, axis=-1))
        self._bias = _Linear(lfe[self._bias_f, self._bias_e])
        self._gravity = _Linear(-np.einsum("b,fbin,i->fn", mass, y, np.array([0.0, -model.gravity])))
        self._rows_t = np.ascontiguousarray(self.points.rows.T)
        self._n = n

    def mass_matrix_from(self, features):
        """M from the features (..., F) (array or Jet), shape (..., n, n)."""
        pairs = _take(features, self._pair_i) * _take(features, self._pair_j)
        return self._mass(pairs).reshape(features.shape[:-1] + (self._n, self._n))

    def bias_from(self, features, v):
        """c(q, q') from the features (..., F) and q' (..., n) (arrays, or Jets of one order), shape (..., n)."""
        if isinstance(features, Jet):
            w = Jet(jets.inexact(v.d) @ self._rows_t)
            w2 = w * w
            psi = features[..., 1:] * Jet(np.concatenate([w2.d, w2.d], axis=-1))  # [cos, sin] omega^2
        else:
            w2 = (jets.inexact(v) @ self._rows_t) ** 2
            psi = features[..., 1:] * np.concatenate([w2, w2], axis=-1)
        return self._bias(_take(features, self._bias_f) * _take(psi, self._bias_e)) + self._gravity(features)


__all__ = ["StackedDynamics", "StackedPoints"]
