"""Tune the running process for the planner and the simulator: one BLAS thread, glibc's heap kept.

Importing fpr changes nothing process-wide. A program that plans or simulates a lot opts in with one
call, early (the command lines ``python -m fpr.plan``, ``fpr.bench``, ``fpr.studies`` and ``fpr.campaign``
make it first thing in their ``main()``, and the campaign's workers make it too)::

    import fpr
    fpr.tune_process()

It does two things, each left alone when the user already chose:

* **BLAS on one thread.** The planner and the simulator work on many small matrices, where a
  multi-threaded BLAS only adds synchronisation (its threads spin against the computation on a
  machine with few cores). ``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS`` and ``MKL_NUM_THREADS`` are set
  to 1 (child processes and a numpy loaded later read them), and the BLAS libraries already loaded are
  limited to one thread (threadpoolctl). Skipped when any of the three variables is set: export one
  yourself to choose another number.
* **Freed memory kept in glibc's heap** (Linux with glibc only). The planner's evaluations with
  derivatives allocate and free arrays of a few MB to a few hundred MB; with glibc's defaults those
  above the mmap threshold are mapped afresh at every call and the top of the heap is given back, so
  each call pays the kernel's page faults again. ``mallopt`` sets the mmap threshold to 32 MiB (its
  maximum), the trim threshold to 1 GiB and the top padding to 256 MiB: the process then keeps up to
  1 GiB of freed memory for reuse. Skipped when ``MALLOC_TRIM_THRESHOLD_``, ``MALLOC_MMAP_THRESHOLD_``
  or ``MALLOC_TOP_PAD_`` is set, or ``FPR_MALLOC_TUNING=0``.

The allocator settings change no result (the same plan, bit for bit, with or without them). The number of
BLAS threads can change the last bits of a result (a multi-threaded BLAS splits its sums differently): the
command lines all run BLAS on one thread, so a program that calls :func:`tune_process` gets their bytes.
Both settings are process-wide and cannot be undone (glibc's stay for the process's life), which is why
importing fpr does not make them.
"""

from __future__ import annotations

import ctypes
import os
import sys
from dataclasses import dataclass

#: The environment variables that choose the number of BLAS threads (OpenBLAS, OpenMP, MKL).
BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: glibc's environment variables that choose what :func:`tune_process` would set.
MALLOC_VARIABLES = ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TOP_PAD_")
#: ``mallopt`` parameters (malloc.h) and the values set [bytes].
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
MMAP_THRESHOLD = 32 << 20
TRIM_THRESHOLD = 1 << 30
TOP_PAD = 256 << 20


# what the first call did (None: not asked yet); later calls report it
_BLAS_DONE: int | None = None
_ALLOCATOR_DONE: bool | None = None


@dataclass(frozen=True)
class Tuning:
    """What :func:`tune_process` did.

    Attributes:
        blas_threads: the BLAS thread count set (1), or None when the user's choice was left alone.
        allocator: whether glibc's allocator settings were applied (False: not glibc, or the user chose).
    """

    blas_threads: int | None
    allocator: bool


def tune_process(blas: bool = True, allocator: bool = True) -> Tuning:
    """Tune this process for planning and simulation (module docstring); idempotent.

    Args:
        blas: limit BLAS to one thread (unless one of :data:`BLAS_VARIABLES` is set).
        allocator: keep freed memory in glibc's heap (unless one of :data:`MALLOC_VARIABLES` is set, or
            ``FPR_MALLOC_TUNING=0``).

    Returns:
        The :class:`Tuning` applied.
    """
    global _BLAS_DONE, _ALLOCATOR_DONE
    if blas and _BLAS_DONE is None:
        _BLAS_DONE = _one_blas_thread()
    if allocator and _ALLOCATOR_DONE is None:
        _ALLOCATOR_DONE = _keep_freed_memory()
    return Tuning(blas_threads=_BLAS_DONE if blas else None, allocator=bool(_ALLOCATOR_DONE) if allocator else False)


def _one_blas_thread() -> int | None:
    if any(name in os.environ for name in BLAS_VARIABLES):
        return None
    for name in BLAS_VARIABLES:
        os.environ[name] = "1"
    if "numpy" in sys.modules:  # its BLAS has started its threads: the variables come too late for it
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=1, user_api="blas")
    return 1


def _keep_freed_memory() -> bool:
    if os.environ.get("FPR_MALLOC_TUNING", "1") == "0" or any(name in os.environ for name in MALLOC_VARIABLES):
        return False
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt  # glibc's (musl has none: AttributeError)
    except (OSError, AttributeError):
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD) & mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD)
                & mallopt(_M_TOP_PAD, TOP_PAD))
