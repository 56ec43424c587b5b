"""fpr/model/_multibody.c on inputs the Python side never builds: corrupted constants vectors and specs, wrong
sizes. Each call either works or raises (ValueError, TypeError), never reads out of bounds."""

import numpy as np
import pytest

import fpr
from fpr.model.multibody import kernel
from fpr.sim.plant import Plant, hover_configuration

pytestmark = pytest.mark.skipif(kernel is None, reason="fpr.model._multibody is not built (no C compiler)")


@pytest.fixture(scope="module")
def plant():
    """The prototype's plant with its compiled constants and drone point spec exported."""
    robot = fpr.load("prototype")
    plant = Plant.from_minimal(robot, hover_configuration(robot, robot.kind.reference_chain))
    plant._export()
    return plant


@pytest.mark.parametrize("joint", [1e10, 2.0**31, 2.0**32 + 1.0, -1e10, np.nan, np.inf, 1e300])
def test_points_refuse_a_joint_out_of_range(plant, joint):
    """A point's joint far out of range (whose cast to int is undefined, INT_MIN on x86) is refused, not read
    at o[INT_MIN]."""
    spec = plant._point_spec.copy()
    spec[1] = joint
    with pytest.raises(ValueError):
        kernel.points(plant._plant_constants, plant.qc, spec)
