"""fpr: model, plan and control a Flying Parallel Robot and its one-drone lab prototype.

Quick start::

    import fpr
    robot = fpr.load("fpr")            # or fpr.load("prototype"); fpr.ROBOTS lists the built-in ones
    q = robot.configuration(phi=5 * 3.14159 / 4, q21=3.14159 / 2)
    M = robot.mass_matrix(q)           # in the seed thesis' coordinates

See README.md for the command line (``python -m fpr.plan``) and the notebooks.

Importing fpr changes nothing process-wide (no environment variable, no allocator setting). A program that
plans or simulates a lot tunes its process with one call, as the command lines do (:mod:`fpr.tuning`)::

    fpr.tune_process()                 # one BLAS thread, freed memory kept in glibc's heap
"""

_ERRORS = ("FprError", "ShapeError", "SingularityError", "UnknownRobotError", "WorkspaceError")


def __getattr__(name):
    # Pinocchio is imported on first use, so that ``python -m fpr.model.description`` stays light; the errors
    # (which import numpy) too, so that a command line handles Ctrl-C before its first heavy import
    # (fpr.cli.launch).
    if name in _ERRORS:
        from fpr.model import errors

        return getattr(errors, name)
    if name in ("ROBOTS", "load", "register"):
        from fpr import robots

        return robots.BUILTIN if name == "ROBOTS" else getattr(robots, name)
    if name == "Robot":
        from fpr.model.robot import Robot

        return Robot
    if name in ("tune_process", "Tuning"):
        from fpr import tuning

        return getattr(tuning, name)
    raise AttributeError(f"module 'fpr' has no attribute {name!r}")


__version__ = "0.1.0"

__all__ = [
    "FprError",
    "ROBOTS",
    "Robot",
    "ShapeError",
    "SingularityError",
    "Tuning",
    "UnknownRobotError",
    "WorkspaceError",
    "load",
    "register",
    "tune_process",
]
