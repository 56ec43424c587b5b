"""fpr keeps freed memory in glibc's heap (fpr/__init__.py ``_tune_allocator``), unless told not to."""

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt: Linux only")

# A 20 MB array, allocated then freed: glibc's defaults map it on its own (mmap threshold 128 KiB) and
# the heap stays small; with fpr's settings (threshold 32 MiB) it comes from the heap, which keeps it.
PROBE = """
import numpy as np
a = np.ones(20 * 2**20 // 8); a[::4096] += 1.0; del a
heap = [line.split()[0] for line in open('/proc/self/maps') if line.rstrip().endswith('[heap]')]
size = sum(int(e, 16) - int(b, 16) for b, e in (h.split('-') for h in heap))
print(fpr.ALLOCATOR_TUNED, size >> 20)
"""


def _probe(**env_vars) -> tuple[str, int]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("MALLOC_", "FPR_MALLOC"))}
    env.update(env_vars)
    out = subprocess.run([sys.executable, "-c", "import fpr" + PROBE], env=env, capture_output=True,
                         text=True, timeout=120, check=True)
    tuned, heap_mb = out.stdout.split()
    return tuned, int(heap_mb)


def test_freed_arrays_stay_in_the_heap_when_tuned():
    tuned, heap_mb = _probe()
    if tuned != "True":
        pytest.skip("no glibc mallopt here")
    assert heap_mb >= 20  # the freed 20 MB array's memory is still the heap's


@pytest.mark.parametrize("env", [{"FPR_MALLOC_TUNING": "0"}, {"MALLOC_TOP_PAD_": "131072"}])
def test_a_user_choice_of_the_allocator_is_left_alone(env):
    tuned, heap_mb = _probe(**env)
    assert tuned == "False" and heap_mb < 20  # glibc's defaults: the array was mapped on its own
