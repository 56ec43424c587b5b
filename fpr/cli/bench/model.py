"""Model section of the benchmark (``python -m fpr.bench --section model``).

All items run in one process, one after the other, so that their ratios mean something on a shared,
noisy machine. Each is a loop sized to last ~50 ms (20 ms with ``--quick``), repeated 7 times (3 with
``--quick``), garbage collector off; reported: median and min over repeats of the time per call
(``time.perf_counter``), the time per sample, and a ratio (per-sample time / a reference's):

1. The FPR :class:`~fpr.model.robot.Robot` in thesis coordinates (mass matrix, nonlinear effects, drone
   Jacobians, forward dynamics, attitude model) against the raw Pinocchio calls underneath (``crba``,
   ``nonLinearEffects``, ``computeJointJacobians`` + ``getFrameJacobian``, ``aba``): the ratio is the
   wrapper's overhead. Random states near ``phi = 5 pi / 4, q21 = pi / 2``.
2. The closed-form planar model (:mod:`fpr.model.planar`), batched over N = 1000, against Pinocchio per call.
3. :func:`fpr.model.inverse_dynamics.inverse_dynamics` along a sine motion of N = 2000 samples (FPR,
   prototype), against one minimal forward dynamics call.
4. The closed chain (:func:`fpr.model.constrained.build_closed_chain`): generalised input and constraint
   dynamics per call, against the minimal forward dynamics.

It also prints accuracy figures (not timings): the largest difference between the closed-chain and
the minimal accelerations over 100 random states and inputs, and the round-trip residual inverse
dynamics -> forward dynamics along a 50-sample motion, with d = 0 (exact) and with the default d
(roll rows exact, chain rows off by the p_i perturbation of seed eq. 2.7-2.8).

Timings depend on the machine and its load: no test asserts them. The accuracy figures are asserted,
with tolerances, in tests/test_constrained.py and tests/test_inverse_dynamics.py.
"""

from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin

import fpr
from fpr.cli.bench.timing import Bench, cycling
from fpr.model.constrained import build_closed_chain
from fpr.model.inverse_dynamics import inverse_dynamics
from fpr.model.planar import planar_configuration

SEED = 2024


def random_states(robot, rng, count: int) -> list[tuple]:
    """Random (q, v, thrust, torque) near the reference pose (as in tests/test_constrained.py)."""
    centre = robot.configuration(**dict(zip(robot.layout.chain, robot.kind.reference_chain, strict=True)))
    return [(centre + 0.3 * rng.normal(size=robot.nq), rng.normal(size=robot.nq),
             rng.uniform(3.0, 15.0, robot.n_drones), 0.3 * rng.normal(size=(robot.n_drones, 3)))
            for _ in range(count)]


def smooth_motion(robot, samples: int, duration: float = 3.0) -> np.ndarray:
    """s(t) = s_0 + 0.2 sin(w t + p) and its derivatives 0..4, shape (5, N, n_s) (tests' smooth_motion), s_0 the
    kind's reference chain.
    """
    s0 = np.array(robot.kind.reference_chain)
    omega, phase = np.linspace(1.0, 2.0, len(s0)), np.linspace(0.0, 1.0, len(s0))
    arg = omega * np.linspace(0.0, duration, samples)[:, None] + phase
    return np.array([s0 * (k == 0) + 0.2 * omega**k * np.sin(arg + k * np.pi / 2) for k in range(5)])


def run_timings(bench: Bench) -> None:
    """The timed items 1-4 of the module docstring."""
    rng = np.random.default_rng(SEED)
    r = fpr.load("fpr")
    model, data, fids = r.model, r.data, r.drone_frame_ids
    states = []  # (q, v, thrust, torque, q_pin, v_pin, fext)
    for q, v, f, tau in random_states(r, rng, 64):
        fext = pin.StdVec_Force([pin.Force.Zero() for _ in range(model.njoints)])
        # the wrenches moved to the joints, as r.forward_dynamics does
        for w, fid in zip(r.input_wrenches(f, tau), fids, strict=True):
            fext[model.frames[fid].parentJoint] += model.frames[fid].placement.act(pin.Force(w))
        states.append((q, v, f, tau, r.to_pinocchio(q), r.to_pinocchio(v), fext))
    zero = np.zeros(model.nv)

    def raw_jacobians(qp):
        pin.computeJointJacobians(model, data, qp)
        return [pin.getFrameJacobian(model, data, f, pin.LOCAL) for f in fids]

    crba, nle, jac, aba = "pin.crba", "pin.nonLinearEffects", "pin.computeJointJacobians+getFrameJacobian", "pin.aba"
    for name, fn, ref in (
            (crba, lambda *s: pin.crba(model, data, s[4]), ()),
            ("fpr r.mass_matrix", lambda *s: r.mass_matrix(s[0]), (crba,)),
            (nle, lambda *s: pin.nonLinearEffects(model, data, s[4], s[5]), ()),
            ("fpr r.nonlinear_effects", lambda *s: r.nonlinear_effects(s[0], s[1]), (nle,)),
            (jac, lambda *s: raw_jacobians(s[4]), ()),
            ("fpr r.drone_jacobians", lambda *s: r.drone_jacobians(s[0]), (jac,)),
            (aba, lambda *s: pin.aba(model, data, s[4], s[5], zero, s[6]), ()),
            ("fpr r.forward_dynamics", lambda *s: r.forward_dynamics(*s[:4]), (aba,)),
            ("fpr r.attitude_model", lambda *s: r.attitude_model(s[0], s[1]), (crba, nle, jac))):
        bench.time(name, cycling(fn, states), ref=ref)

    planar = r.planar("rigid")
    big = random_states(r, rng, 1000)
    qs = planar_configuration(r, np.array([s[0] for s in big]))
    vs = planar_configuration(r, np.array([s[1] for s in big]))
    bench.time("planar rigid mass_matrix(Q), N=1000", lambda: planar.mass_matrix(qs), n=len(qs), ref=(crba,))
    bench.time("planar rigid bias(Q, V), N=1000", lambda: planar.bias(qs, vs), n=len(qs), ref=(nle,))

    proto = fpr.load("prototype")
    bench.time("prototype r.forward_dynamics", cycling(proto.forward_dynamics, random_states(proto, rng, 64)))
    for robot in (r, proto):
        motion = smooth_motion(robot, 2000)
        bench.time(f"{robot.name} inverse_dynamics, N=2000", functools.partial(inverse_dynamics, robot, motion),
                   n=2000, ref=(f"{robot.name} r.forward_dynamics",))
    for robot in (r, proto):
        closed = build_closed_chain(robot)
        args = []  # (q_c, v_c, thrust, torque, J_c^T w)
        for q, v, f, tau in random_states(robot, rng, 64):
            qc, vc = closed.from_minimal(q, v)
            args.append((qc, vc, f, tau, closed.generalized_input(qc, f, tau)))
        for name, fn in _closed_chain_calls(closed):
            bench.time(f"{robot.name} closed {name}", cycling(fn, args), ref=(f"{robot.name} r.forward_dynamics",))


def _closed_chain_calls(closed) -> tuple:
    """The closed chain's timed items: (name, function of (q_c, v_c, thrust, torque, J_c^T w)) pairs."""
    return (("generalized_input", lambda qc, vc, f, tau, g: closed.generalized_input(qc, f, tau)),
            ("forward_dynamics", lambda qc, vc, f, tau, g: closed.forward_dynamics(qc, vc, g)),
            ("generalized_input+forward_dynamics", lambda qc, vc, f, tau, g: closed.forward_dynamics(
                qc, vc, closed.generalized_input(qc, f, tau))))


#: goal of the FPR mass matrix M(q) in thesis coordinates, one call [s]
MASS_MATRIX_GOAL_S = 5e-6


def model_targets(results: list[dict]) -> list[dict]:
    """The model section's goals with their values and verdicts (rows of ``Bench.results``)."""
    row = next((r for r in results if r["name"] == "fpr r.mass_matrix"), None)
    if row is None:
        return []
    return [dict(target="FPR mass matrix M(q), one call (median) <= 5 us", value=row["median_s"],
                 goal=MASS_MATRIX_GOAL_S, unit="s", met=bool(row["median_s"] <= MASS_MATRIX_GOAL_S))]


def run_residuals() -> list[dict]:
    """Accuracy figures of item 5 of the module docstring (maximum absolute errors)."""
    rng = np.random.default_rng(SEED + 1)
    out = []
    for name in fpr.ROBOTS:
        robot = fpr.load(name)
        closed = build_closed_chain(robot)
        worst = scale = 0.0
        for q, v, f, tau in random_states(robot, rng, 100):
            a = robot.forward_dynamics(q, v, f, tau)
            qc, vc, expected = closed.from_minimal(q, v, a)
            ac = closed.forward_dynamics(qc, vc, closed.generalized_input(qc, f, tau))
            worst, scale = max(worst, np.abs(ac - expected).max()), max(scale, np.abs(expected).max())
        out.append(dict(name=f"{name} max |a_closed - a_minimal|", value=float(worst), samples=100,
                        max_abs_acceleration=float(scale)))
        for d in dict.fromkeys((0.0, robot.hinge_offset)):  # once for a robot without a hinge offset
            model = fpr.load(name, hinge_offset=0.0) if d == 0.0 else robot
            inputs = inverse_dynamics(model, smooth_motion(model, 50))
            q, v, a = inputs.full_state(model)
            err = np.abs([model.forward_dynamics(q[k], v[k], inputs.thrust[k], inputs.torque[k]) - a[k]
                          for k in range(len(q))])
            rows = {"all rows": slice(None)} if d == 0.0 else {
                "roll rows": model.indices(model.layout.rolls),
                "chain rows": model.indices(model.layout.chain)}
            for label, idx in rows.items():
                out.append(dict(name=f"{name} round trip d={d:g}, {label}", value=float(err[:, idx].max()),
                                samples=len(q)))
    return out
