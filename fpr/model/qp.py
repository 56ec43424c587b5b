"""ProxQP, loaded at its first use so that its results do not depend on where its memory happens to lie.

``import proxsuite`` picks the most vectorised of its builds the CPU runs (AVX-512, else AVX2, else
the portable one). The vectorised builds' sums peel to the alignment of buffers that ProxQP
allocates inside ``solve``, and the heap hands them out at 16-byte boundaries that differ from run
to run (with the hash seed, the command's arguments, anything allocated before): the same QP then
gives results that differ in the last bits (measured: 2 distinct results over 60 identical
``proxqp.dense.solve`` calls with the AVX2 and AVX-512 builds, 1 with the portable build). The
planner's SQP amplifies those bits into plans that differ run to run. The portable build does not
depend on alignment, and on the planner's and the allocator's small QPs it is as fast.

proxsuite (0.8) has no public way to choose its build: its ``__init__`` asks its
``proxsuite.instructionset`` module which builds the CPU runs and imports the first that loads, and a
process can hold one build only (nanobind refuses to load a second). :func:`proxsuite_module` therefore
imports proxsuite with a stand-in for ``proxsuite.instructionset`` that reports no vector extension,
for the duration of that import only. Nothing happens when fpr is imported: the SQP and the allocator
call :func:`proxsuite_module` when they first need ProxQP (a step QP that neither the active set nor the
interior point solved, the composite curvature's QPs, the allocation's fallback route), so a process that
never needs it never imports proxsuite. (Importing proxsuite sets ``KMP_DUPLICATE_LIB_OK`` in the environment:
proxsuite's own doing, at that first use.)
Solvers that need no such choice were tried in ProxQP's place and fell short on the step QPs of the
singularity crossing (nearly dependent rows, next to no curvature): quadprog's dual method called some of
them inconsistent and lost others to round-off (with proximal steps added, the crossing's J grew), DAQP
reported cycling, and OSQP's answers made the crossing's J far worse.

If ``proxsuite`` was imported the usual way before the first use, that build is kept and
:data:`DETERMINISTIC` is False.
"""

from __future__ import annotations

import sys
import types

#: Whether the ProxQP in use is the portable build (results independent of memory alignment).
DETERMINISTIC = False


def proxsuite_module():
    """The ``proxsuite`` package, with its portable build when this is the first import of it."""
    global DETERMINISTIC
    if "proxsuite" not in sys.modules:
        # proxsuite/__init__.py asks proxsuite.instructionset which builds the CPU can run: say none
        stub = types.ModuleType("proxsuite.instructionset")
        stub.has_AVX512F = stub.has_AVX2 = lambda: False
        sys.modules["proxsuite.instructionset"] = stub
        try:
            import proxsuite
        finally:
            if sys.modules.get("proxsuite.instructionset") is stub:
                del sys.modules["proxsuite.instructionset"]
    import proxsuite

    build = getattr(getattr(proxsuite, "_submodule", None), "__name__", "")
    DETERMINISTIC = build.rpartition(".")[2] == "proxsuite_pywrap"
    return proxsuite
