"""Test configuration: the test process tuned as the command lines tune theirs (one BLAS thread, freed memory
kept in glibc's heap: fpr.tune_process), before numpy is imported; the replanner's latency model pinned for the
whole session (FPR_CALIBRATION).
"""

import json

import pytest
from helpers import planned_hover

import fpr

fpr.tune_process()

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


@pytest.fixture(scope="module", params=["fpr", "prototype"])
def hover(request):
    """The planar robots at rest at a hover pose (:func:`helpers.planned_hover`): robot, configuration (rolls from the
    plan), the plan's inputs and the controller's reference.
    """
    return planned_hover(request.param)
