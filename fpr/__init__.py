"""fpr: model, plan and control a Flying Parallel Robot and its one-drone lab prototype.

Quick start::

    import fpr
    robot = fpr.load("fpr")            # or fpr.load("prototype"); fpr.ROBOTS lists the built-in ones
    q = robot.configuration(phi=5 * 3.14159 / 4, q21=3.14159 / 2)
    M = robot.mass_matrix(q)           # in the seed thesis' coordinates

See README.md for the command line (``python -m fpr.plan``) and the notebooks.
"""

import os as _os

# The planner and the simulator work on many small matrices, where multi-threaded BLAS only adds
# synchronisation: measured 5-10x slower on a shared 2-core machine. This takes effect when fpr is
# imported before numpy (the command-line tools, the tests); export the variables to override.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

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
