"""fpr: model, plan and control a Flying Parallel Robot and its one-drone lab prototype.

Quick start::

    import fpr
    robot = fpr.load("fpr")            # or fpr.load("prototype"); fpr.ROBOTS lists the built-in ones
    q = robot.configuration(phi=5 * 3.14159 / 4, q21=3.14159 / 2)
    M = robot.mass_matrix(q)           # in the seed thesis' coordinates

See README.md for the command line (``python -m fpr.plan``) and the notebooks.
"""

import os as _os

import sys as _sys

# The planner and the simulator work on many small matrices, where multi-threaded BLAS only adds
# synchronisation: measured 5-10x slower on a shared 2-core machine (CPU time doubled). Before numpy
# is loaded the environment variables do it; when numpy was imported first (a notebook, a script that
# imports numpy before fpr) its BLAS has already started its threads, so threadpoolctl limits them.
# Export OPENBLAS_NUM_THREADS (or OMP_/MKL_) yourself to choose another number: fpr then leaves BLAS alone.
_BLAS_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
_user_chose_blas_threads = any(_var in _os.environ for _var in _BLAS_VARS)
for _var in _BLAS_VARS:
    _os.environ.setdefault(_var, "1")
if "numpy" in _sys.modules and not _user_chose_blas_threads:
    from threadpoolctl import threadpool_limits as _threadpool_limits

    _threadpool_limits(limits=1, user_api="blas")

from fpr.model.errors import FprError, ShapeError, SingularityError, UnknownRobotError, WorkspaceError  # noqa: E402


def __getattr__(name):
    # Pinocchio is imported on first use, so that ``python -m fpr.model.description`` stays light.
    if name in ("ROBOTS", "load", "register"):
        from fpr import robots

        return robots.BUILTIN if name == "ROBOTS" else getattr(robots, name)
    if name == "Robot":
        from fpr.model.robot import Robot

        return Robot
    raise AttributeError(f"module 'fpr' has no attribute {name!r}")


__version__ = "0.1.0"

__all__ = [
    "FprError",
    "ROBOTS",
    "Robot",
    "ShapeError",
    "SingularityError",
    "UnknownRobotError",
    "WorkspaceError",
    "load",
    "register",
]
