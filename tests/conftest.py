"""Test configuration: single-threaded BLAS before numpy is imported (see fpr/__init__.py)."""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
