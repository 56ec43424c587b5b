"""Importing fpr changes nothing process-wide; ``fpr.tune_process()`` keeps freed memory in glibc's heap.

Each check runs in a fresh interpreter. The allocator's state is read through glibc: a 1 MiB block is mapped on
its own (``mallinfo2().hblkhd`` grows by it) under glibc's defaults (mmap threshold 128 KiB), and comes from the
heap once the threshold is 32 MiB.
"""

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator: Linux only")

#: What the planner, the simulator and the command lines import.
MODULES = ("fpr", "fpr.tuning", "planners.optimize", "planners.methods", "fpr.sim.closed_loop", "fpr.sim.plant",
           "controllers.allocation", "controllers.ctc", "fpr.views.figures", "fpr.views.scene", "fpr.cli.plan",
           "fpr.cli.studies", "fpr.cli.bench", "fpr.cli.campaign", "fpr.robustness.runner")

PROBE = """
import ctypes, json, os, sys
class Mallinfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                "fsmblks", "uordblks", "fordblks", "keepcost")]
libc = ctypes.CDLL(None)
if not hasattr(libc, "mallinfo2"):
    print(json.dumps(None)); sys.exit()
libc.mallinfo2.restype = Mallinfo2
libc.malloc.restype, libc.malloc.argtypes, libc.free.argtypes = ctypes.c_void_p, [ctypes.c_size_t], [ctypes.c_void_p]
before = dict(os.environ)
for name in MODULES:
    __import__(name)
after_import = dict(os.environ)
TUNE
mapped = libc.mallinfo2().hblkhd
block = libc.malloc(1 << 20)
mapped = libc.mallinfo2().hblkhd - mapped >= 1 << 20
libc.free(block)
changed = sorted(k for k in set(before) | set(after_import) if before.get(k) != after_import.get(k))
blas = {k: os.environ.get(k) for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
print(json.dumps({"changed_by_import": changed, "mapped": bool(mapped), "tuning": TUNING, "blas_env": blas}))
"""


def _probe(tune: str = "", **env_vars) -> dict:
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("MALLOC_", "FPR_MALLOC")) and k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                                       "MKL_NUM_THREADS")}
    env.update(env_vars)
    code = (PROBE.replace("MODULES", repr(MODULES)).replace("TUNE", tune or "tuning = None")
            .replace("TUNING", "None if tuning is None else [tuning.blas_threads, tuning.allocator]"))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    found = json.loads(out.stdout.strip().splitlines()[-1])
    if found is None:
        pytest.skip("glibc without mallinfo2 (before 2.33)")
    return found


def test_importing_fpr_and_its_modules_changes_neither_the_environment_nor_the_allocator():
    found = _probe()
    assert found["changed_by_import"] == []
    assert found["mapped"]  # glibc's default mmap threshold: the 1 MiB block is a mapping of its own
    assert found["blas_env"] == {"OPENBLAS_NUM_THREADS": None, "OMP_NUM_THREADS": None, "MKL_NUM_THREADS": None}


def test_tune_process_sets_one_blas_thread_and_keeps_freed_memory_in_the_heap():
    found = _probe("import fpr\ntuning = fpr.tune_process()")
    assert found["tuning"] == [1, True]
    assert not found["mapped"]  # mmap threshold 32 MiB: the block comes from the heap
    assert found["blas_env"] == {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def test_a_command_lines_main_tunes_its_process():
    found = _probe("import fpr.cli.plan, contextlib, io\nwith contextlib.redirect_stdout(io.StringIO()):\n"
                   "    fpr.cli.plan.main(['--help'])\nfrom fpr.tuning import tune_process\ntuning = tune_process()")
    assert found["tuning"] == [1, True] and not found["mapped"]


@pytest.mark.parametrize("env", [{"FPR_MALLOC_TUNING": "0"}, {"MALLOC_TOP_PAD_": "131072"}])
def test_a_user_choice_of_the_allocator_is_left_alone(env):
    found = _probe("import fpr\ntuning = fpr.tune_process()", **env)
    assert found["tuning"] == [1, False] and found["mapped"]


# A 20 MB array, allocated then freed: glibc's defaults map it on its own and the heap stays small; after
# tune_process (threshold 32 MiB) it comes from the heap, which keeps it (trim threshold 1 GiB).
HEAP = """
import numpy as np
import fpr
tuning = fpr.tune_process() if TUNE else None
a = np.ones(20 * 2**20 // 8); a[::4096] += 1.0; del a
heap = [line.split()[0] for line in open('/proc/self/maps') if line.rstrip().endswith('[heap]')]
print(sum(int(e, 16) - int(b, 16) for b, e in (h.split('-') for h in heap)) >> 20)
"""


@pytest.mark.parametrize("tune", [True, False])
def test_freed_arrays_stay_in_the_heap_only_when_tuned(tune):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("MALLOC_", "FPR_MALLOC"))}
    out = subprocess.run([sys.executable, "-c", HEAP.replace("TUNE", str(tune))], env=env, capture_output=True,
                         text=True, timeout=120, check=True)
    heap_mb = int(out.stdout.strip())
    assert (heap_mb >= 20) == tune
