"""``python -m fpr.plan``: plan a mission of the FPR and report what the drones must do.

This first version evaluates the *stop-at-every-way-point* motion of a mission (9th-degree
segments with zero velocity, acceleration, jerk and snap at each way point, seed 3.2.2): it
computes the drones' thrusts, rolls, torques and rotor speeds by inverse dynamics, checks them
against the limits, prints a summary and writes ``trajectory.csv`` and ``plan.json``. The
optimised methods (``two-step``, ``one-step``, seed 3.2.4) come with the planner issue.

Exit codes: 0 feasible, 1 a limit is violated (results are still written), 2 bad input.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

import fpr
from fpr.errors import FprError
from fpr.inverse_dynamics import inverse_dynamics
from fpr.kinematics import fpr_workspace_margins, singularity_margin
from planners.polynomial import PiecewisePolynomial, stop_points

S0 = [0.0, 0.0, 5 * np.pi / 4, np.pi / 2]
MISSIONS = {
    # DESIGN.md "Reference missions": way positions s = [y z phi q21] and travel times [s]
    "square": {"positions": [S0, [1.0, 0.0, 5 * np.pi / 4, np.pi / 2], [1.0, 1.0, 5 * np.pi / 4, np.pi / 2],
                             [0.0, 1.0, 5 * np.pi / 4, np.pi / 2], S0], "times": [3.0, 3.0, 3.0, 3.0]},
    "study": {"positions": [[0.0, 0.0, 3.9270, 1.5708], [1.0, 1.0, 3.9270, 1.5708]], "times": [3.0]},
}


def evaluate(robot, positions, times, rate: float) -> dict:
    """Stop-at-way-points motion through ``positions`` and its inverse dynamics, sampled at ``rate`` [Hz]."""
    trajectory = PiecewisePolynomial(stop_points(np.asarray(positions, dtype=float)), np.asarray(times, dtype=float))
    t, motion = trajectory.sample(rate, order=4)
    inputs = inverse_dynamics(robot, motion)
    w = inputs.rotor_speed
    margins = fpr_workspace_margins(motion[0], robot.link_length, robot.margins)
    limit = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    checks = {name: float(np.min(value)) for name, value in margins.items()}
    checks["rotor_speed_low"] = float(w.min())
    checks["rotor_speed_high"] = float(limit - w.max())
    checks["roll"] = float(np.pi / 2 - robot.margins.angle - np.abs(inputs.roll).max())
    summary = {
        "J_e": float(np.trapezoid(inputs.power.sum(axis=1), t)),
        "J_phi": float(np.trapezoid((inputs.roll_rate**2).sum(axis=1), t)),
        "peak_rotor_force_N": float(robot.rotor_constants.thrust_coefficient * inputs.rotor_speed_squared.max()),
        "peak_rotor_speed_rad_s": float(w.max()),
        "peak_thrust_N": float(inputs.thrust.max()),
        "least_ground_clearance_m": float((inputs.joint_position[..., 1] + robot.link_length).min()),
        "least_singularity_margin_rad": float(singularity_margin(motion[0][:, 3]).min()),
        "constraint_margins": checks,
        "feasible": bool(min(checks.values()) >= 0),
    }
    return {"t": t, "motion": motion, "inputs": inputs, "trajectory": trajectory, "summary": summary}


def write_csv(path: Path, t, motion, inputs) -> None:
    """One row per sample; units in README.md."""
    names = ["y", "z", "phi", "q21"]
    header = ["t"] + names + [n + "_d" for n in names] + [n + "_dd" for n in names]
    n_d = inputs.thrust.shape[1]
    for i in range(1, n_d + 1):
        header += [f"y_j{i}", f"z_j{i}", f"phi{i}", f"phi{i}_d", f"f{i}", f"tau{i}_x", f"tau{i}_y", f"tau{i}_z"]
        header += [f"w{i}_{m}" for m in range(1, 5)]
    columns = [t[:, None], motion[0], motion[1], motion[2]]
    for i in range(n_d):
        columns += [inputs.joint_position[:, i], inputs.roll[:, i:i + 1], inputs.roll_rate[:, i:i + 1],
                    inputs.thrust[:, i:i + 1], inputs.torque[:, i], inputs.rotor_speed[:, i]]
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        writer.writerows(np.round(np.hstack(columns), 9).tolist())


def main(argv=None) -> int:
    """Command line entry point."""
    parser = argparse.ArgumentParser(prog="python -m fpr.plan", description=__doc__.split("\n\n")[0])
    parser.add_argument("--mission", default="square", choices=sorted(MISSIONS), help="built-in mission")
    parser.add_argument("--method", default="none", choices=["none", "two-step", "one-step"],
                        help="'none': stop at every way point (the optimisers are not available yet)")
    parser.add_argument("--rate", type=float, default=200.0, help="sample rate of trajectory.csv [Hz]")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default fpr-out/<mission>)")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    args = parser.parse_args(argv)
    if args.method != "none":
        print(f"error: --method {args.method} is not available yet; use --method none", file=sys.stderr)
        return 2
    if not np.isfinite(args.rate) or args.rate <= 0:
        print(f"error: --rate {args.rate} must be a positive number of samples per second", file=sys.stderr)
        return 2
    out = args.out or Path("fpr-out") / args.mission
    try:
        robot = fpr.load("fpr")
        mission = MISSIONS[args.mission]
        result = evaluate(robot, mission["positions"], mission["times"], args.rate)
    except (FprError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "trajectory.csv", result["t"], result["motion"], result["inputs"])
    summary = result["summary"]
    plan = {"mission": {"name": args.mission, **mission}, "method": args.method, "robot": robot.parameters,
            "summary": summary, "points": result["trajectory"].points.tolist(),
            "durations": result["trajectory"].durations.tolist()}
    (out / "plan.json").write_text(json.dumps(plan, indent=2), encoding="utf-8")
    if not args.quiet:
        print(f"mission {args.mission}: stop-at-every-way-point motion, {len(result['t'])} samples at {args.rate:g} Hz")
        rows = [("J_e (energy index)", summary["J_e"], "J"), ("J_phi (perturbation index)", summary["J_phi"], "rad^2/s"),
                ("peak thrust", summary["peak_thrust_N"], "N"), ("peak rotor force", summary["peak_rotor_force_N"], "N"),
                ("peak rotor speed", summary["peak_rotor_speed_rad_s"], "rad/s"),
                ("least ground clearance", summary["least_ground_clearance_m"], "m"),
                ("least singularity margin", summary["least_singularity_margin_rad"], "rad")]
        for name, value, unit in rows:
            print(f"  {name:28s} {value:12.4f} {unit}")
        for name, margin in summary["constraint_margins"].items():
            if margin < 0:
                print(f"  VIOLATED {name}: by {-margin:.4g}")
        print(f"wrote {out / 'trajectory.csv'} and {out / 'plan.json'}")
    return 0 if summary["feasible"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
