"""``fpr.tune_process()`` runs BLAS on one thread, whether numpy was imported before or after; importing fpr alone
leaves BLAS as numpy started it (fpr/tuning.py).
"""

import os
import subprocess
import sys

import pytest

PROBE = ("from threadpoolctl import threadpool_info; "
         "print(sorted({i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'}))")


def _blas_threads(code: str, **env_vars) -> str:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    env.update(env_vars)
    out = subprocess.run([sys.executable, "-c", code + PROBE], env=env, capture_output=True, text=True,
                         timeout=120, check=True)
    return out.stdout.strip()


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="BLAS starts one thread anyway on one core")
def test_import_leaves_blas_alone_and_tune_process_sets_one_thread():
    alone = _blas_threads("import numpy; ")
    assert alone != "[1]"  # the probe can tell: numpy alone starts more threads
    assert _blas_threads("import numpy; import fpr, planners.optimize, fpr.sim.closed_loop; ") == alone
    assert _blas_threads("import numpy; import fpr; fpr.tune_process(); ") == "[1]"
    assert _blas_threads("import fpr; fpr.tune_process(); import numpy; ") == "[1]"


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="needs two cores to choose two threads")
def test_a_user_choice_of_blas_threads_is_left_alone():
    assert _blas_threads("import numpy; import fpr; fpr.tune_process(); ", OPENBLAS_NUM_THREADS="2") == "[2]"
