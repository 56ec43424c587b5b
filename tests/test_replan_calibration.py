"""The replanner's latency on the machine that runs it (planners/replanning/latency.py): the model, the
per-machine file, measured once and read back, pinned; the least horizon of a replan.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import fpr
from fpr.model.errors import PlannerArgumentError
from planners.missions.mission import load_mission
from planners.optimize import plan
from planners.replanning.latency import (
    FEATURES,
    LatencyModel,
    load_latency,
    machine,
    machine_latency,
    read_calibration,
    write_calibration,
)
from planners.replanning.replanner import Replanner, ReplanOptions, calibration_mission, measure_latency


def test_the_model_is_linear_in_the_work():
    model = LatencyModel((1e-3, 2e-3, 1e-4, 5e-5, 1e-3))
    work = {"nodes": 21, "derivative_evaluations": 2, "value_evaluations": 3, "horizon_s": 4.0}
    assert model.latency(work) == pytest.approx(1e-3 + 2 * 2e-3 + 21 * 2 * 1e-4 + 21 * 3 * 5e-5 + 4 * 1e-3)
    assert len(FEATURES) == len(model.costs)


@pytest.mark.parametrize("costs", [(1.0, 2.0), (-1e-3, 0, 0, 0, 0), (float("nan"), 0, 0, 0, 0)])
def test_the_model_refuses_absurd_costs(costs):
    with pytest.raises(PlannerArgumentError, match="latency"):
        LatencyModel(costs)


def test_the_machines_file_is_measured_once_and_read_back_to_the_bit(tmp_path):
    """No file: measured (the given function, once) and written; the model used then is the one every later
    run reads. Another machine's file is measured again; a robot the file lacks is added to it.
    """
    path = tmp_path / "fpr" / "replan-latency.json"
    robot = fpr.load("fpr")
    calls = []

    def measure(r):
        calls.append(r.name)
        return LatencyModel((0.1 / 3, 2e-3, 1.7e-4, 0.0, 1.1e-5), "measured")

    first = machine_latency(robot, measure, path)
    second = machine_latency(robot, measure, path)
    assert calls == ["fpr"] and first == second and first.costs == (0.1 / 3, 2e-3, 1.7e-4, 0.0, 1.1e-5)
    document = json.loads(path.read_text())
    assert document["machine"] == machine() and set(document["robots"]) == {"fpr"}
    machine_latency(fpr.load("prototype"), measure, path)
    assert calls == ["fpr", "prototype"] and set(read_calibration(path)["robots"]) == {"fpr", "prototype"}
    document["machine"] = {**document["machine"], "host": "elsewhere"}
    path.write_text(json.dumps(document))
    machine_latency(robot, measure, path)
    assert calls[-1] == "fpr" and len(calls) == 3  # another machine's calibration: measured here again
    with pytest.raises(PlannerArgumentError, match="no replanning latency"):
        machine_latency(robot, None, tmp_path / "none.json")


def test_a_run_is_pinned_by_a_calibration_file_or_by_a_replans_json(tmp_path):
    model = LatencyModel((0.0, 1e-3, 2e-4, 0.0, 0.0), "pinned")
    write_calibration(tmp_path / "cal.json", "fpr", model)
    assert load_latency(tmp_path / "cal.json", "fpr") == model
    (tmp_path / "replans.json").write_text(json.dumps({"latency_model": model.to_dict(), "replans": []}))
    assert load_latency(tmp_path / "replans.json", "fpr") == model
    with pytest.raises(PlannerArgumentError, match="prototype"):
        load_latency(tmp_path / "cal.json", "prototype")
    with pytest.raises(PlannerArgumentError, match="cannot read"):
        load_latency(tmp_path / "missing.json", "fpr")


def test_measuring_fits_this_machines_replans():
    """The calibration times real replans and fits them: non-negative costs, a positive latency for a replan
    of its mission (how close the model is to the wall clock is the bench's to say, over many replans).
    """
    robot = fpr.load("prototype")
    model = measure_latency(robot, repeats=1)
    assert all(c >= 0 for c in model.costs) and model.source.startswith("measured on this machine")
    result = plan(calibration_mission(robot), "none", robot=robot)
    record = Replanner(result, ReplanOptions(latency=model)).replan(0.3, "check")
    assert model.latency(record.work) > 0


def test_a_short_horizon_takes_the_next_travel_too():
    """A replan splicing 0.5 s before the next way point re-optimises through the one after it (least_horizon),
    unless told not to.
    """
    result = plan(load_mission("square"), "none")
    model = LatencyModel((0.0,) * 5)
    for least, end in ((1.0, 2), (0.0, 1)):
        replanner = Replanner(result, ReplanOptions(latency=model, least_horizon=least))
        record = replanner.replan(2.45, "rate")
        assert record.way_point == end, record.why
    replanner = Replanner(result, ReplanOptions(latency=model, least_horizon=10.0))
    assert replanner.replan(2.45, "rate").way_point == 4  # the whole rest of the mission at most
    with pytest.raises(PlannerArgumentError, match="least_horizon"):
        ReplanOptions(least_horizon=-1.0)
    assert np.isfinite(replanner.replans[-1].J)
