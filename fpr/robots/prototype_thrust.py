"""The prototype's thrust from motion through its Type-2 singularity q2 = 0 (seed 3.37, ch. 4).

The prototype's chain obeys J_pr(xi)^T F = b, b = M_pt xi'' + c_pt (seed 3.37, the drone a point mass at
its joint). With e = u(q1 + q2) along the second link and e_perp = u_perp(q1 + q2) across it, the columns
of J_pr are L (u_perp(q1) + e_perp) and L e_perp, so writing F = f_r e + f_p e_perp
(:func:`link_components`, :func:`force_from_link_components`)::

    b2 = L f_p,      b1 - b2 (1 + cos q2) = L f_r sin q2 = g.

The component across the link, f_p, is regular everywhere; the tension f_r = g / (L sin q2) is a 0/0
limit at q2 = 0 when the motion meets the crossing criterion (seed 4.7: at q2 = 0, g = -[-1 2] b = 0,
:mod:`fpr.robots.prototype_singularity`). Two users of this split:

* the planner's inverse dynamics, :func:`thrust_vector`: the limit computed exactly along a motion, by
  deflating the Taylor polynomials of g and sin q2 at the crossing;
* the controller's outer loop, :func:`regularised_force`: the tension at one measured state,
  regularised towards the planned one near q2 = 0.

Both work on plain arrays and on :class:`~fpr.model.jets.Jet` (the split is arithmetic only).
"""

from __future__ import annotations

import numpy as np

from fpr.model import jets
from fpr.model.jets import Jet

#: |sin q2| below which a sample is examined for a nearby crossing of q2 = 0 (and the motion's 5th
#: and 6th derivatives are used, when given).
SINGULAR_SCREEN = 5e-2

#: Largest time [s] between a sample and the crossing (the root of sin q2's Taylor polynomial) at
#: which the link tension's limit is computed by deflation. Beyond it the plain quotient is accurate
#: (its error in F'' grows like eps / (q2' dt^3): ~1e-6 of the value at 3 ms and q2' = 0.2 rad/s).
SINGULAR_TIME = 3e-3

#: Largest criterion residual g(t*) [N m], relative to 1 + the size of g's Taylor coefficients,
#: for which the crossing is taken as meeting the criterion (finite force). A larger one is a real
#: singularity: the plain quotient is kept, and the force there is as large as it really is.
CRITERION_TOLERANCE = 1e-6


def link_components(b1, b2, cos_q2, link_length: float):
    """(g, f_p): the tension's right-hand side g = b1 - b2 (1 + cos q2) = L sin(q2) f_r [N m] and the
    force across the second link f_p = b2 / L [N] (arrays or Jets).
    """
    return b1 - b2 * (1.0 + cos_q2), b2 / link_length


def force_from_link_components(f_r, f_p, sin_e, cos_e):
    """(F_y, F_z) = f_r e + f_p e_perp, e = (cos, sin)(q1 + q2) given by ``sin_e``, ``cos_e`` [N] (arrays or Jets)."""
    return f_r * cos_e - f_p * sin_e, f_r * sin_e + f_p * cos_e


def thrust_vector(motion: Jet, generalized: Jet, link_length: float, order: int) -> Jet:
    """The prototype's thrust vector F from J_pr^T F = b (seed 3.37), exact through q2 = 0.

    The tension f_r = g / (L sin q2) (module docstring) loses every digit near q2 = 0 as a plain
    quotient. So at a sample where q2 crosses 0 nearby (cos q2 > 0, a simple real root t* of sin q2's
    Taylor polynomial within :data:`SINGULAR_TIME`) *and* g(t*) vanishes there (within
    :data:`CRITERION_TOLERANCE`), both Taylor polynomials are deflated by (t - t*) and
    f_r = g~ / s~, without cancellation (:func:`deflated_quotient`). Everywhere else, a grazing
    q2 = 0 and a crossing that misses the criterion included, the plain quotient is used: the force
    there is really large.

    Args:
        motion: xi = [q1, q2] as a Jet of order K, shape (N, 2).
        generalized: b = M xi'' + c (point-mass drone), Jet of order >= ``order``, shape (N, 2).
        link_length: L [m].
        order: derivative order of F wanted. Deflation needs K >= order + 4 (F, F', F'' need xi up
            to its 6th derivative: with one order less the truncated Taylor polynomials leave, at
            3 ms from a crossing at 2.5 rad/s, ~1e-3 N in F and ~10 rad/s^2 in the roll
            acceleration; tested); with less, the plain quotient is used.

    Returns:
        F, Jet of the given order, shape (N, 2) [N].
    """
    xi = motion
    q12 = xi[..., 0] + xi[..., 1]
    s_e, c_e = jets.sincos(q12.truncate(order))
    sin2 = jets.sin(xi[..., 1])
    b1, b2 = generalized[..., 0], generalized[..., 1]
    g, f_p = link_components(b1, b2, jets.cos(xi[..., 1].truncate(b1.order)), link_length)
    with np.errstate(divide="ignore", invalid="ignore"):
        plain = g.truncate(order) / sin2.truncate(order)
    d = plain.d.copy()
    near = (np.abs(np.real(sin2.value)) < SINGULAR_SCREEN) & (np.cos(np.real(xi.value[..., 1])) > 0)
    if np.any(near) and g.order >= order + 2:
        k = min(g.order, sin2.order) + 1  # every Taylor coefficient available (more = more accurate)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            quotient, root, remainder, size = deflated_quotient(g.d[:k, near], sin2.d[:k, near], order)
        use = (np.isfinite(np.real(root)) & (np.abs(np.real(root)) <= SINGULAR_TIME)
               & (np.abs(np.real(remainder)) <= CRITERION_TOLERANCE * (1.0 + size)))
        index = np.flatnonzero(near)[use]
        d[:, index] = quotient[:, use]
    f_r = Jet(d) / link_length
    fy, fz = force_from_link_components(f_r, f_p.truncate(order), s_e, c_e)
    return jets.stack([fy, fz], axis=-1)


def regularised_force(xi, b, planned, link_length: float, band: float) -> np.ndarray:
    r"""F from J_pr^T F = b at one state, the tension regularised towards the planned one (the controller's).

    Near q2 = 0 the row L sin(q2) f_r = g cannot be inverted; it is solved in the least-squares sense,
    regularised towards the planned tension f_r,d = F_d . e (the plan satisfies the crossing criterion,
    so f_r,d is finite):

    .. math:: f_r = \frac{L \sin q_2\, g + \epsilon^2 f_{r,d}}{(L \sin q_2)^2 + \epsilon^2}, \quad
              \epsilon^2 = \varepsilon^2 \max(0, 1 - (L \sin q_2 / 10 \varepsilon)^2), \quad
              \varepsilon = L \sin(\mathrm{band}).

    Where |sin q2| >= 10 sin(band) this is the plain solve exactly (and within (eps / L sin q2)^2 closer
    in); near q2 = 0 the elbow's motion across the straight chain, which no drone force can act on,
    follows the plan open loop.

    Args:
        xi: measured [q1, q2], shape (2,) [rad].
        b: M_pt u + c_pt, shape (2,) [N m].
        planned: the plan's F at this instant, shape (2,) [N].
        link_length: L [m].
        band: the regularisation angle [rad].

    Returns:
        F, shape (2,) [N].
    """
    q12 = xi[0] + xi[1]
    along = np.array([np.cos(q12), np.sin(q12)])
    g, f_p = link_components(b[0], b[1], np.cos(xi[1]), link_length)
    lever = link_length * np.sin(xi[1])
    eps2 = (link_length * np.sin(band)) ** 2
    # tapered off for |L sin q2| >= 10 eps: the plain CTC law there (within ~1 % before)
    eps2 *= max(0.0, 1.0 - lever**2 / (100.0 * eps2))
    f_r = (lever * g + eps2 * (planned @ along)) / (lever**2 + eps2)
    return np.array(force_from_link_components(f_r, f_p, along[1], along[0]))


def deflated_quotient(num: np.ndarray, den: np.ndarray, order: int):
    """Derivatives 0..order of num/den at samples where den has a simple root t* near 0.

    ``num``, ``den``: derivatives 0..k-1 (leading axis, k >= order + 2) of each function at the samples.
    Both Taylor polynomials are divided by (eps - eps*), eps* the root of den's polynomial found
    by Newton's method from -den/den', and the quotient's Taylor coefficients follow from the
    deflated ones. Analytic in the inputs (complex-step safe).

    Returns:
        (derivatives (order+1, N), eps* (N,) [s], the dropped remainder num(t*) (N,), the size of num's
        Taylor coefficients (N,)), for the caller to accept the deflation or not.
    """
    k = num.shape[0]
    fact = np.cumprod(np.r_[1.0, np.arange(1, k)])[:, None]
    a = num / fact  # Taylor coefficients a_0..a_{k-1}
    c = den / fact
    root = -c[0] / c[1]
    for _ in range(6):
        value = sum(c[j] * root**j for j in range(k))
        slope = sum(j * c[j] * root ** (j - 1) for j in range(1, k))
        root = root - value / slope

    def deflate(p):
        q = [None] * (k - 1)
        q[k - 2] = p[k - 1]
        for j in range(k - 3, -1, -1):
            q[j] = p[j + 1] + root * q[j + 1]
        return q, p[0] + root * q[0]

    (at, remainder), (ct, _) = deflate(a), deflate(c)
    f = []
    for j in range(order + 1):
        acc = at[j] - sum(f[i] * ct[j - i] for i in range(j))
        f.append(acc / ct[0])
    size = np.max(np.abs(np.real(a)), axis=0)
    return np.stack(f) * fact[:order + 1], root, remainder, size


__all__ = ["CRITERION_TOLERANCE", "SINGULAR_SCREEN", "SINGULAR_TIME", "deflated_quotient", "force_from_link_components",
           "link_components", "regularised_force", "thrust_vector"]
