"""What an evaluation of the planning NLP gives (:class:`Evaluation`), the cache of the last one
(:func:`cached_evaluation`), and the store through which the problems of one plan share their grid nodes'
derivatives (:class:`NodeDerivatives`); the NLP itself is :class:`planners.problem.motion.MotionProblem`.
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Evaluation:
    """Objective and constraints of one motion on the optimisation grid.

    Attributes:
        J: weighted, normalised objective (3.26).
        terms: [J_e, J_phi] on the grid (J_e with the smoothed |.|) [J, rad^2/s].
        constraints: windowed minima of the scaled constraint rows, shape (n_windows * R,).
        gradient: dJ/dx, shape (n_x,), or None.
        jacobian: d constraints / dx, shape (n_windows * R, n_x), or None (a property: the array given
            as ``dense_jacobian``, or made from ``jacobian_sparse`` on first use when only that was given).
        hessian: Gauss-Newton approximation of d^2 J / dx^2 (positive semi-definite), or None; a
            :class:`~planners.problem.banded.Banded` matrix from :class:`MotionProblem` (``numpy.asarray`` makes
            the array), an array from other problems.
        power, power_weight, power_jacobian: the drone powers P_k = F_i . r_i' at every node (K = N n_d,
            [W]), their weights a_e w_k in J (J = sum_k a_e w_k |P_k|_eps + a_phi J_phi) and their
            derivatives (K, n_x): the SQP models the sum of |P_k| piecewise linearly (or None;
            ``power_jacobian`` is a property like ``jacobian``: ``dense_power_jacobian`` or made from
            ``power_jacobian_sparse``).
        rate_hessian: the Gauss-Newton matrix of the a_phi J_phi part alone (or None; banded like ``hessian``).
        jacobian_sparse: ``jacobian`` as a scipy CSR matrix (same numbers), or None. :class:`MotionProblem`
            gives the CSR matrix alone (each row touches one segment's two points: the SQP's route works on it,
            with work linear in the mission's length), and ``jacobian`` makes the dense array when asked for.
        power_jacobian_sparse: ``power_jacobian`` likewise (CSR, or None).
        power_gram: ``power_gram(w)`` = sum_k w_k grad P_k grad P_k^T (w (K,) >= 0), the Gauss-Newton sum of the
            powers with the weights given, assembled segment by segment as ``hessian`` is (or None: then
            :mod:`planners.optimisation.curvature` forms it from ``power_jacobian``).
    """

    J: float
    terms: np.ndarray
    constraints: np.ndarray
    gradient: np.ndarray | None = None
    dense_jacobian: np.ndarray | None = None
    hessian: np.ndarray | None = None
    power: np.ndarray | None = None
    power_weight: np.ndarray | None = None
    dense_power_jacobian: np.ndarray | None = None
    rate_hessian: np.ndarray | None = None
    jacobian_sparse: object | None = None
    power_jacobian_sparse: object | None = None
    power_gram: object | None = None

    @property
    def jacobian(self) -> np.ndarray | None:
        """d constraints / dx as an array (from ``jacobian_sparse`` on first use when only that was given)."""
        return self._dense("dense_jacobian", "jacobian_sparse")

    @property
    def power_jacobian(self) -> np.ndarray | None:
        """d P_k / dx as an array (from ``power_jacobian_sparse`` on first use when only that was given)."""
        return self._dense("dense_power_jacobian", "power_jacobian_sparse")

    def _dense(self, name: str, sparse_name: str):
        dense = getattr(self, name)
        if dense is None and getattr(self, sparse_name) is not None:
            dense = getattr(self, sparse_name).toarray()
            object.__setattr__(self, name, dense)  # kept: the same array on every access
        return dense

    @property
    def violation(self) -> float:
        """Largest constraint violation (0 when every constraint holds) [scaled units]."""
        return float(max(0.0, -self.constraints.min()))


def cached_evaluation(evaluate):
    """Keep the last result of an NLP's ``evaluate(self, x, derivatives=False) -> Evaluation``.

    The solvers ask for J, the constraints and their derivatives at one x in separate calls: the
    decorated method computes once per x (a result with derivatives also serves a call without
    them). The last result is kept in ``self._cache``; x reaches ``evaluate`` as a float array.
    """
    @functools.wraps(evaluate)
    def cached(self, x, derivatives: bool = False) -> Evaluation:
        x = np.asarray(x, dtype=float)
        key = x.tobytes()
        last = getattr(self, "_cache", None)
        if last is not None and last[0] == key and (last[1] or not derivatives):
            return last[2]
        result = evaluate(self, x, derivatives)
        self._cache = (key, derivatives, result)
        return result

    return cached


class NodeDerivatives:
    """The grid nodes' quantities and their sensitivities, segment by segment, of the last
    evaluation with derivatives of each :class:`MotionProblem` given this store
    (:meth:`MotionProblem.share_node_derivatives`), for the problems of one plan to share
    (:mod:`planners.methods.two_step`: one store per attempt, its travels and its polish).

    A node's quantities and their derivatives with respect to its motion jet depend on its segment's two
    points, its duration and the grid alone, not on the problem (its free entries, scaling, weights): a
    problem whose every segment is one that another problem's last evaluation with derivatives had (the
    2-step polish starts where the travels of step 2 ended, :mod:`planners.methods.two_step`) takes their
    numbers instead of computing them again. Points match when each entry is within 4 ulp of the stored one
    (a way through x and back, ``points_of(x_of(p))``, may change the last bit).
    """

    def __init__(self):
        self._segments: dict = {}  # (samples per segment, duration's bytes) -> [(owner, points (2, 5, n), data)]
        self._owned: dict = {}  # owner -> its keys in _segments
        self._owners = itertools.count()

    def owner(self) -> int:
        """A new owner's number (a problem's; not its id(), which a later problem may get again)."""
        return next(self._owners)

    def put(self, owner: int, points, durations, k: int, data: list) -> None:
        """Keep ``owner``'s evaluation (``data[i]`` for segment i), replacing its earlier one."""
        for key in self._owned.pop(owner, ()):
            self._segments[key] = [e for e in self._segments[key] if e[0] != owner]
        keys = [(k, d.tobytes()) for d in durations]
        for i, key in enumerate(keys):
            self._segments.setdefault(key, []).append((owner, points[i:i + 2], data[i]))
        self._owned[owner] = set(keys)

    def get(self, points, durations, k: int) -> list | None:
        """The data of every segment of a motion (``points``, ``durations``, ``k`` nodes per segment), or
        None when one of them is not in the store.
        """
        found = []
        for i, d in enumerate(durations):
            ends = points[i:i + 2]
            hit = next((data for _, stored, data in self._segments.get((k, d.tobytes()), ())
                        if np.all(np.abs(stored - ends) <= 4 * np.finfo(float).eps * np.abs(ends))), None)
            if hit is None:
                return None
            found.append(hit)
        return found


__all__ = ["Evaluation", "NodeDerivatives", "cached_evaluation"]
