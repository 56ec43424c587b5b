"""The same plan, bit for bit, in fresh interpreters with different hash seeds and heap layouts.

The singularity crossing is the planner's most sensitive NLP: a last-bit difference in one QP step
(ProxQP's vectorised builds sum in an order that depends on the alignment of the memory they get,
see :mod:`fpr.model.qp`) grew into plans whose J differed in the 4th digit. The crossing here runs
with one start and no grid refinement, which is enough to show that difference (with the vectorised
ProxQP, two such runs differ in their points) and takes about a third of the full mission's time.
"""

import json
import os
import subprocess
import sys

#: Plan the crossing mission, print its points, durations and J as exact hex floats (one JSON line).
#: ``sys.argv[1]`` is padding whose length moves what the heap holds before the plan.
SCRIPT = """
import json, sys
padding = [bytearray(n) for n in range(1, len(sys.argv[1]) + 1)]
from planners.crossing.solve import CROSSING_STARTS
from planners.missions.mission import load_mission
from planners.methods import crossing
from fpr.model import qp
mission = load_mission("cross-singularity")
robot = mission.load_robot()
start, end, duration, n_via = crossing._task(mission, robot)
from planners.crossing.solve import optimise_crossing
outcome = optimise_crossing(robot, start, end, duration, n_via, alpha=mission.alpha, starts=CROSSING_STARTS[:1],
                            max_refinements=0)
trajectory = outcome.trajectory
print(json.dumps({
    "points": [float(v).hex() for v in trajectory.points.reshape(-1)],
    "durations": [float(v).hex() for v in trajectory.durations],
    "J": [float(outcome.report.J_e).hex(), float(outcome.report.J_phi).hex()],
    "deterministic_qp": qp.DETERMINISTIC or "proxsuite" not in sys.modules,  # ProxQP portable, or not needed
}))
"""


def _plan(hash_seed: str, padding: str) -> dict:
    env = dict(os.environ, PYTHONHASHSEED=hash_seed)
    done = subprocess.run([sys.executable, "-c", SCRIPT, padding], env=env, capture_output=True, text=True,
                          timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_crossing_plan_is_identical_under_two_hash_seeds():
    first = _plan("1", "x")
    second = _plan("2", "x" * 37)
    assert first["deterministic_qp"] and second["deterministic_qp"]
    assert first["durations"] == second["durations"]
    differing = [i for i, (a, b) in enumerate(zip(first["points"], second["points"], strict=True)) if a != b]
    assert not differing, f"{len(differing)} of {len(first['points'])} point entries differ, e.g. " \
                          f"{[(first['points'][i], second['points'][i]) for i in differing[:3]]}"
    assert first["J"] == second["J"]


def _square(out, **env_vars) -> dict[str, bytes]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("MALLOC_", "FPR_MALLOC"))
           and k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    env.update(env_vars)
    done = subprocess.run([sys.executable, "-m", "fpr.plan", "--mission", "square", "--no-plots", "--quiet",
                           "--out", str(out)], env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    return {name: (out / name).read_bytes() for name in ("plan.json", "trajectory.csv")}


def test_the_same_command_gives_the_same_bytes_with_or_without_the_allocator_tuning(tmp_path):
    """Two runs of ``python -m fpr.plan --mission square`` (different hash seeds) write the same plan.json and
    trajectory.csv, and so does a run that keeps glibc's allocator defaults (FPR_MALLOC_TUNING=0): where freed
    memory goes changes the speed, not the result. The number of BLAS threads may change the last bits: every
    command line runs BLAS on one thread (fpr.tuning).
    """
    first = _square(tmp_path / "a", PYTHONHASHSEED="1")
    assert _square(tmp_path / "b", PYTHONHASHSEED="2") == first
    assert _square(tmp_path / "c", PYTHONHASHSEED="3", FPR_MALLOC_TUNING="0") == first
