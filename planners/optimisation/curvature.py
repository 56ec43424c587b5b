"""The SQP's ``"smoothed"`` curvature model of the planning objective's sum of absolute values.

J = a_phi J_phi + sum_k pw_k |P_k| (J_e: the drone powers P_k at the grid nodes, seed 3.24-3.26; the
objective itself smooths |P| as sqrt(P^2 + eps^2) - eps with eps = 0.01 W). A Gauss-Newton model of
h(P(x)) keeps the outer function's curvature and drops P's own: grad P^T h''(P) grad P.

* The default Gauss-Newton matrix of :class:`planners.problem.motion.MotionProblem` gives each term the
  majoriser curvature 1 / |P_k| (a reweighted least-squares model: the quadratic through |P| that
  touches it at +-P_k). Along a step that moves P_k by dP with |dP| >> |P_k|, that quadratic grows as
  dP^2 / (2 |P_k|) where |P| grows as |dP|: it makes every step far too short, and the SQP stops
  1 % above the optimum of the square (305 iterations to reach 0.5036 at tolerance 1e-6).
* This model gives each term h''(P) of a wider smoothing, sqrt(P^2 + mu^2) with mu = ``width``
  (0.1 W): mu^2 / (P^2 + mu^2)^(3/2), large only within about mu of a sign change of P (where |P|
  bends), small where P keeps its sign (where |P| is linear in P), plus ``share`` (0.05) times the
  majoriser, which keeps the model's Hessian well conditioned (the active-set QP, planners.optimisation.active_set,
  needs it) and its steps inside the region where the linearisation of P holds. Measured with the
  planner's defaults (dense-grid J, SQP iterations of all stages): square one-step 0.5046
  in 19 iterations (Gauss-Newton: 0.5087, stopped after 12, 0.5036 only after 305), tour one-step
  0.6853 in 52, study n_vp = 3 0.6661 in 24. A share of 0.1 takes 34, 45 and 26 iterations there;
  there the model's predictions fell short of the actual decrease (ratios 1.3-1.8 on the square).
  At 0.05 they are close to 1, and trying longer steps (``SqpOptions.extrapolate``) no longer pays
  (28 and 84 iterations instead of 27 and 80 for the two-step square and tour): it is off.

The model is only the QP's curvature: the trust-region ratio test of :mod:`planners.optimisation.sqp` judges every
step on the exact merit, so a model that is too bold is corrected by shorter steps. (The figures above are
with the QP's steps as they come, the default; ``SqpOptions.kinks`` cuts them, below.)

**Step length** (:func:`along_step`). The smoothed curvature spreads the bend of each |P_k| over +-mu: a step
that takes a power from far on one side of zero to far on the other is predicted the linear decrease of |P_k|
where |P_k| actually stays or grows. Such steps were rejected at zero violation (ratios of -0.5 on random
missions), the trust region fell by 4 per rejection and grew back by 2 per very successful step. A second model
of the merit along the QP's direction d, with each power linearised but its (eps-smoothed) absolute value kept
exact, is convex in the step's length t, costs a few vector operations per t, and predicts the actual decrease
to within a few per cent where the quadratic model was off in sign: with ``SqpOptions(kinks=True)`` the SQP takes
the step to its minimiser on (0, 1] and judges it by that model's decrease (an option: see
:mod:`planners.optimisation.sqp`, "Step length").
"""

from __future__ import annotations

import numpy as np

from planners.problem.motion import POWER_CURVATURE_FLOOR, POWER_SMOOTHING

#: mu of the model's smoothing of |P| [W] (module docstring).
POWER_WIDTH = 0.1
#: Share of the majoriser curvature 1 / |P| kept in the model (module docstring).
MAJORISER_SHARE = 0.05


def power_curvature(power, width: float = POWER_WIDTH, share: float = MAJORISER_SHARE) -> np.ndarray:
    """h''(P) per term [1/W]: mu^2 / (P^2 + mu^2)^(3/2) + share / max(|P|_eps, floor) (module docstring)."""
    p = np.asarray(power, dtype=float)
    smooth = np.sqrt(p * p + POWER_SMOOTHING**2)
    return width**2 / (p * p + width**2) ** 1.5 + share / np.maximum(smooth, POWER_CURVATURE_FLOOR)


def smoothed_hessian(ev, width: float = POWER_WIDTH, share: float = MAJORISER_SHARE):
    """The model's Hessian at an Evaluation with the power fields (``power_model``; module docstring).

    J_phi's Gauss-Newton matrix (``rate_hessian``) plus sum_k pw_k h''(P_k) grad P_k grad P_k^T, in the
    problem's scaled variables: banded (:class:`~planners.problem.banded.Banded`) when the evaluation assembles
    the powers' sum itself (``power_gram``: :class:`~planners.problem.motion.MotionProblem`, segment by segment),
    else from ``power_jacobian``. Without the power fields: the problem's Gauss-Newton matrix.
    """
    if getattr(ev, "power", None) is None:
        return ev.hessian
    weight = ev.power_weight * power_curvature(ev.power, width, share)
    if getattr(ev, "power_gram", None) is not None:
        return ev.rate_hessian + ev.power_gram(weight)
    pj = ev.power_jacobian
    return np.asarray(ev.rate_hessian) + pj.T @ (weight[:, None] * pj)


def along_step(ev, d, penalty: float, predicted: float) -> tuple[np.ndarray, float]:
    """The step t d, t in (0, 1], that minimises the merit's model with J_e's kinks along d, and its predicted
    decrease.

    The model along d: J_phi's Gauss-Newton quadratic, J_e = sum_k pw_k |P_k|_eps with each power linearised
    (P_k + t dP_k) inside the objective's own smoothed absolute value, and the l1 penalty of the linearised
    constraints,

        m(t) = t g_phi^T d + t^2 d^T H_phi d / 2 + sum_k pw_k (|P_k + t dP_k|_eps - |P_k|_eps)
               + rho (v(c + t A d) - v(c))

    (v the l1 violation), is convex in t (each term is), so its minimiser on [0, 1] is found by bisection on m'(t).
    The QP's own model
    (:mod:`planners.optimisation.curvature`) gives |P| a smoothed curvature: where a step takes powers across zero
    from afar it underestimates the cost of the kink and predicts a decrease where J grows. Here each |P_k| is
    exact in P_k, so the predicted decrease follows the actual one up to the powers' own nonlinearity and the
    constraints' curvature. Returns (d, ``predicted``) unchanged when m does not decrease along d (m'(0) >= 0).
    """
    pv, pw = ev.power, ev.power_weight
    dp = ev.power_jacobian_sparse @ d if getattr(ev, "power_jacobian_sparse", None) is not None \
        else ev.power_jacobian @ d
    eps2 = POWER_SMOOTHING**2
    smooth = np.sqrt(pv * pv + eps2)
    g_phi_d = float(ev.gradient @ d) - float(pw @ (pv / smooth * dp))
    dhd = float(d @ (ev.rate_hessian @ d))
    c = np.asarray(ev.constraints)
    ad = _constraint_jacobian(ev) @ d
    pwdp = pw * dp

    def slope(t: float) -> float:
        p = pv + t * dp
        kinks = float(pwdp @ (p / np.sqrt(p * p + eps2)))
        return g_phi_d + t * dhd + kinks - penalty * float(ad[c + t * ad < 0.0].sum())

    if slope(0.0) >= 0.0:
        return d, predicted
    t = 1.0
    if slope(1.0) > 0.0:
        low, high = 0.0, 1.0
        for _ in range(50):
            mid = 0.5 * (low + high)
            low, high = (mid, high) if slope(mid) < 0.0 else (low, mid)
        t = high
    p = pv + t * dp
    model = t * g_phi_d + 0.5 * t * t * dhd + float(pw @ (np.sqrt(p * p + eps2) - smooth)) \
        + penalty * (_l1(c + t * ad) - _l1(c))
    return t * d, -model


def _l1(c) -> float:
    """The l1 violation sum_i max(0, -c_i)."""
    return float(np.maximum(0.0, -np.asarray(c)).sum())


def _constraint_jacobian(ev):
    """The constraints' Jacobian of an Evaluation: its sparse copy when it has one."""
    sparse_copy = getattr(ev, "jacobian_sparse", None)
    return ev.jacobian if sparse_copy is None else sparse_copy
