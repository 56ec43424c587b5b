"""Benchmark of the dynamics models: ``python -m fpr.bench [--quick] [--json]``.

All items run in one process, one after the other, so that their ratios mean something on a shared,
noisy machine. Each is a loop sized to last ~50 ms (20 ms with ``--quick``), repeated 7 times (3 with
``--quick``), garbage collector off; reported: median and min over repeats of the time per call
(``time.perf_counter``), the time per sample, and a ratio (per-sample time / a reference's):

1. The FPR :class:`~fpr.robots.Robot` in thesis coordinates (mass matrix, nonlinear effects, drone
   Jacobians, forward dynamics, attitude model) against the raw Pinocchio calls underneath (``crba``,
   ``nonLinearEffects``, ``computeJointJacobians`` + ``getFrameJacobian``, ``aba``): the ratio is the
   wrapper's overhead. Random states near ``phi = 5 pi / 4, q21 = pi / 2``.
2. The closed-form planar model (:mod:`fpr.planar`), batched over N = 1000, against Pinocchio per call.
3. :func:`fpr.inverse_dynamics.inverse_dynamics` along a sine motion of N = 2000 samples (FPR,
   prototype), against one minimal forward dynamics call.
4. The closed chain (:func:`fpr.constrained.build_closed_chain`): generalised input and constraint
   dynamics per call, against the minimal forward dynamics.

It also prints accuracy figures (not timings): the largest difference between the closed-chain and
the minimal accelerations over 100 random states and inputs, and the round-trip residual inverse
dynamics -> forward dynamics along a 50-sample motion, with d = 0 (exact) and with the default d
(roll rows exact, chain rows off by the p_i perturbation of seed eq. 2.7-2.8).

Timings depend on the machine and its load: no test asserts them. The accuracy figures are asserted,
with tolerances, in tests/test_constrained.py and tests/test_inverse_dynamics.py.
"""

from __future__ import annotations

import argparse
import gc
import itertools
import json
import os
import platform
import sys
import time

import numpy as np
import pinocchio as pin

import fpr
from fpr.constrained import build_closed_chain
from fpr.inverse_dynamics import inverse_dynamics
from fpr.planar import planar_configuration

SEED = 2024
REFERENCE = {  # the chain's reference pose: FPR (y, z, phi, q21), prototype (q1, q2)
    "fpr": (0.0, 0.0, 5 * np.pi / 4, np.pi / 2), "prototype": (0.3, 1.2)}


def random_states(robot, rng, count: int) -> list[tuple]:
    """Random (q, v, thrust, torque) near the reference pose (as in tests/test_constrained.py)."""
    centre = robot.configuration(**dict(zip(robot.layout.chain, REFERENCE[robot.name])))
    return [(centre + 0.3 * rng.normal(size=robot.nq), rng.normal(size=robot.nq),
             rng.uniform(3.0, 15.0, robot.n_drones), 0.3 * rng.normal(size=(robot.n_drones, 3)))
            for _ in range(count)]


def smooth_motion(name: str, samples: int, duration: float = 3.0) -> np.ndarray:
    """s(t) = s_0 + 0.2 sin(w t + p) and its derivatives 0..4, shape (5, N, n_s) (tests' smooth_motion)."""
    s0 = np.array(REFERENCE[name])
    omega, phase = np.linspace(1.0, 2.0, len(s0)), np.linspace(0.0, 1.0, len(s0))
    arg = omega * np.linspace(0.0, duration, samples)[:, None] + phase
    return np.array([s0 * (k == 0) + 0.2 * omega**k * np.sin(arg + k * np.pi / 2) for k in range(5)])


def cycling(fn, args: list[tuple]):
    """A no-argument callable that calls fn on the next argument tuple of args, round robin."""
    pool = itertools.cycle(args)
    return lambda: fn(*next(pool))


class Bench:
    """Times items one after the other and keeps the results.

    Attributes:
        repeats: repeats of each timed loop.
        target: duration of one timed loop [s].
        progress: whether to print one line per item on stderr.
        results: one dict per item (name, median_s, min_s, n, per_sample_s, loops, repeats, ratio, ratio_to).
    """

    def __init__(self, repeats: int, target: float, progress: bool):
        self.repeats, self.target, self.progress = repeats, target, progress
        self.results: list[dict] = []

    @staticmethod
    def _loop(fn, loops: int) -> float:
        start = time.perf_counter()
        for _ in range(loops):
            fn()
        return time.perf_counter() - start

    def time(self, name: str, fn, n: int = 1, ref: tuple[str, ...] = ()) -> dict:
        """Time fn (one call handles n samples); ratio = per-sample time / sum of the refs' per-sample times."""
        fn()  # warm up (caches, lazy imports)
        gc.disable()
        try:
            loops, elapsed = 1, self._loop(fn, 1)
            while elapsed < self.target / 10:
                loops *= 4
                elapsed = self._loop(fn, loops)
            loops = max(1, round(loops * self.target / elapsed))
            per_call = sorted(self._loop(fn, loops) / loops for _ in range(self.repeats))
        finally:
            gc.enable()
        median = float(np.median(per_call))
        known = {r["name"]: r["per_sample_s"] for r in self.results}
        ratio = median / n / sum(known[r] for r in ref) if ref else None
        result = dict(name=name, median_s=median, min_s=per_call[0], n=n, per_sample_s=median / n, loops=loops,
                      repeats=self.repeats, ratio=ratio, ratio_to=" + ".join(ref) or None)
        self.results.append(result)
        if self.progress:
            print(f"bench [{len(self.results):2d}] {name}: {fmt(median)} per call", file=sys.stderr, flush=True)
        return result


def run_timings(bench: Bench) -> None:
    """The timed items 1-4 of the module docstring."""
    rng = np.random.default_rng(SEED)
    r = fpr.load("fpr")
    model, data, fids = r.model, r.data, r.drone_frame_ids
    states = []  # (q, v, thrust, torque, q_pin, v_pin, fext)
    for q, v, f, tau in random_states(r, rng, 64):
        fext = pin.StdVec_Force([pin.Force.Zero() for _ in range(model.njoints)])
        for w, fid in zip(r.input_wrenches(f, tau), fids):  # wrenches moved to the joints, as r.forward_dynamics
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
        motion = smooth_motion(robot.name, 2000)
        bench.time(f"{robot.name} inverse_dynamics, N=2000", lambda: inverse_dynamics(robot, motion), n=2000,
                   ref=(f"{robot.name} r.forward_dynamics",))
    for robot in (r, proto):
        closed = build_closed_chain(robot)
        args = []  # (q_c, v_c, thrust, torque, J_c^T w)
        for q, v, f, tau in random_states(robot, rng, 64):
            qc, vc = closed.from_minimal(q, v)
            args.append((qc, vc, f, tau, closed.generalized_input(qc, f, tau)))
        for name, fn in (("generalized_input", lambda qc, vc, f, tau, g: closed.generalized_input(qc, f, tau)),
                         ("forward_dynamics", lambda qc, vc, f, tau, g: closed.forward_dynamics(qc, vc, g)),
                         ("generalized_input+forward_dynamics", lambda qc, vc, f, tau, g: closed.forward_dynamics(
                             qc, vc, closed.generalized_input(qc, f, tau)))):
            bench.time(f"{robot.name} closed {name}", cycling(fn, args), ref=(f"{robot.name} r.forward_dynamics",))


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
        for d in (0.0, robot.hinge_offset):
            model = fpr.load(name, hinge_offset=0.0) if d == 0.0 else robot
            inputs = inverse_dynamics(model, smooth_motion(name, 50))
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


def fmt(seconds: float) -> str:
    """A duration with a readable unit."""
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if seconds >= scale:
            return f"{seconds / scale:7.3f} {unit}"
    return f"{seconds / 1e-9:7.1f} ns"


def main(argv=None) -> int:
    """Run the benchmark and print the table (or JSON with ``--json``).

    Args:
        argv: command-line arguments (default: sys.argv[1:]).

    Returns:
        the exit status, 0.
    """
    parser = argparse.ArgumentParser(prog="python -m fpr.bench", description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print a JSON document instead of the table")
    parser.add_argument("--quick", action="store_true", help="3 repeats of ~20 ms loops instead of 7 of ~50 ms")
    args = parser.parse_args(argv)
    bench = Bench(repeats=3 if args.quick else 7, target=0.02 if args.quick else 0.05, progress=not args.json)
    info = dict(python=platform.python_version(), numpy=np.__version__, pinocchio=pin.__version__,
                cpu_count=os.cpu_count(), platform=platform.platform())
    run_timings(bench)
    residuals = run_residuals()
    if args.json:
        print(json.dumps(dict(machine=info, repeats=bench.repeats, loop_target_s=bench.target,
                              timings=bench.results, residuals=residuals), indent=2))
        return 0
    print(" ".join(f"{k} {v}" for k, v in info.items()))
    print(f"{bench.repeats} repeats of ~{bench.target * 1e3:.0f} ms loops; times per call, per-sample = median / n")
    width = max(len(r["name"]) for r in bench.results)
    print(f"{'name':<{width}}  {'median':>10}  {'min':>10}  {'per-sample':>10}  ratio (per-sample / ref)")
    for r in bench.results:
        ratio = f"{r['ratio']:8.3f} x {r['ratio_to']}" if r["ratio"] is not None else ""
        print(f"{r['name']:<{width}}  {fmt(r['median_s'])}  {fmt(r['min_s'])}  {fmt(r['per_sample_s'])}  {ratio}")
    print("\naccuracy (max abs acceleration error)")
    for r in residuals:
        print(f"  {r['name']:<{width}}  {r['value']:.3e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
