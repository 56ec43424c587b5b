"""Test configuration: single-threaded BLAS before numpy is imported (see fpr/__init__.py)."""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


import json  # noqa: E402

import pytest  # noqa: E402

#: The replanner's latency model in the tests (planners/replanning/latency.py): pinned, so that no test measures
#: this machine or writes its calibration file, and a test's decisions do not depend on the machine's speed.
TEST_LATENCY = {"costs": [0.002, 0.001, 0.0002, 0.0, 0.0], "source": "the tests' pinned model"}


@pytest.fixture(autouse=True, scope="session")
def _pinned_replanning_latency(tmp_path_factory):
    """FPR_CALIBRATION: a calibration file of this machine holding :data:`TEST_LATENCY` for every robot."""
    from fpr.robots import names
    from planners.replanning.latency import FORMAT, machine

    path = tmp_path_factory.mktemp("calibration") / "replan-latency.json"
    document = {"format": FORMAT, "machine": machine(), "robots": {name: TEST_LATENCY for name in names()}}
    path.write_text(json.dumps(document), encoding="utf-8")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("FPR_CALIBRATION", str(path))
        yield path
