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



def _tune_allocator() -> bool:
    """Keep freed memory in glibc's heap (mallopt), unless the user set MALLOC_* or FPR_MALLOC_TUNING=0.

    The planner's evaluations with derivatives allocate and free arrays of a few MB to a few hundred MB;
    with glibc's defaults, those above the (dynamic) mmap threshold are mapped afresh at every call and
    the top of the heap is given back, so each call pays the kernel's page faults again: up to 0.25 s of
    system time per evaluation of the 1100-variable polish. With the mmap threshold at its 32 MiB maximum,
    a trim threshold of 1 GiB and 256 MiB of top padding, the 32-way-point two-step took 0.88x the time
    (same J bit for bit, same peak memory; README "Planning time"). Returns whether it was applied.
    """
    if _os.environ.get("FPR_MALLOC_TUNING", "1") == "0" or any(
        _var in _os.environ for _var in ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TOP_PAD_")
    ):
        return False
    if not _sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None)
        mallopt = libc.mallopt  # glibc's (musl has none: AttributeError)
    except (OSError, AttributeError):
        return False
    m_trim_threshold, m_top_pad, m_mmap_threshold = -1, -2, -3  # malloc.h
    return bool(
        mallopt(m_mmap_threshold, 32 << 20) & mallopt(m_trim_threshold, 1 << 30) & mallopt(m_top_pad, 256 << 20)
    )


ALLOCATOR_TUNED = _tune_allocator()

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
