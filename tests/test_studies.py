"""The thesis' studies (fpr.studies.thesis, fpr.cli.studies): reference ratios, the trends the maths guarantees,
tables, files.

Small settings (n_vp in {0, 1}, alpha in {0, 1}) on the single-travel ``study`` mission.

Tolerances:

* The reference entries of the ratios are the same floats divided by themselves: exactly 1.
* Two-step, n_vp = 1 against n_vp = 0: step 2 starts from step 1's motion (on a single travel, the
  stop-at-way-points motion) and the SQP only accepts steps that lower its merit, so on the
  optimisation grid J_end <= J_start exactly once feasible; on the dense grid (500 Hz, exact |.|,
  trapezoidal rule) we allow ``DENSE_RTOL`` = 1e-3 relative, the size of the difference between
  the grid's Simpson sums and the dense sums on these motions (about 1e-5 here).
* Alpha trends: the alpha = 0 optimum minimises J_phi among the motions that satisfy the grid
  constraints, and the alpha = 1 optimum is one of them, so J_phi(alpha=0) <= J_phi(alpha=1); the same
  for J_e the other way. This holds for optima; the SQP stops when an iteration improves J (about 1)
  by less than 1e-4, the grid and dense values differ by about 1e-5 relative, and the solver is local:
  we allow ``OPTIMUM_RTOL`` = 1e-3 relative (the observed gaps are factors of 3 to 5).
"""

import dataclasses
import json
import math

import numpy as np
import pytest

from fpr.cli import studies
from fpr.cli.studies import format_table, format_value, write_study_figures
from fpr.model.errors import PlannerArgumentError, UnknownMethodError
from fpr.studies.thesis import (
    AlphaStudy,
    Case,
    ViaPointStudy,
    alpha_study,
    method_comparison,
    via_point_study,
)
from planners.methods import METHODS
from planners.missions.mission import load_mission

DENSE_RTOL = 1e-3
OPTIMUM_RTOL = 1e-3


@pytest.fixture(scope="module")
def robot():
    return load_mission("study").load_robot()


@pytest.fixture(scope="module")
def via(robot):
    lines = []
    study = via_point_study(counts=(0, 1), robot=robot, progress=lines.append)
    assert any("n_vp = 1" in line for line in lines)
    return study


@pytest.fixture(scope="module")
def alpha(robot):
    # alpha = 0 is not feasible on the dense grid (see fpr/studies/thesis.py): no grid refinement here,
    # the trends below concern the optimum of each grid problem
    return alpha_study(alphas=(1.0, 0.0), robot=robot, max_refinements=0)


def test_via_point_reference_ratios_are_one(via: ViaPointStudy):
    i = via.counts.index(0)
    assert via.energy_ratio[i] == 1.0
    assert via.perturbation_ratio[i] == 1.0
    assert via.reference == via.cases[i]


def test_via_point_ratios_divide_by_no_via_point_case(via: ViaPointStudy):
    for case, e, p in zip(via.cases, via.energy_ratio, via.perturbation_ratio, strict=True):
        assert e == case.J_e / via.reference.J_e
        assert p == case.J_phi / via.reference.J_phi
    # single travel: the n_vp = 0 motion is the stop-at-way-points motion (J = 1 exactly)
    assert via.reference.J_e == pytest.approx(via.stop.J_e, rel=1e-12)
    assert via.stop.J == pytest.approx(1.0, abs=1e-12)


def test_one_via_point_is_no_worse_than_none(via: ViaPointStudy):
    j0, j1 = via.J[via.counts.index(0)], via.J[via.counts.index(1)]
    assert j1 <= j0 * (1 + DENSE_RTOL)
    step2 = via.plans[via.counts.index(1)].stages[-1]
    assert step2.violation_end == 0.0
    assert step2.J_end <= step2.J_start  # descent method from step 1's motion, on its own grid
    assert all(via.feasible)


def test_via_point_reference_planned_when_zero_not_asked(via: ViaPointStudy, robot):
    only = via_point_study(counts=(1,), robot=robot, max_iterations=3)
    assert only.counts == (1,) and len(only.cases) == 1
    assert only.reference.label == "n_vp = 0"
    assert only.reference.J_e == via.reference.J_e and only.reference.J_phi == via.reference.J_phi
    assert only.energy_ratio[0] == only.cases[0].J_e / via.reference.J_e
    assert only.perturbation_ratio[0] == only.cases[0].J_phi / via.reference.J_phi


def test_alpha_reference_ratios_are_one(alpha: AlphaStudy):
    assert alpha.energy_ratio[alpha.alphas.index(0.0)] == 1.0
    assert alpha.perturbation_ratio[alpha.alphas.index(1.0)] == 1.0
    assert alpha.energy_reference.alpha == 0.0 and alpha.perturbation_reference.alpha == 1.0


def test_each_alpha_extreme_is_best_for_its_own_objective(alpha: AlphaStudy):
    e = dict(zip(alpha.alphas, alpha.J_e, strict=True))
    p = dict(zip(alpha.alphas, alpha.J_phi, strict=True))
    assert p[0.0] <= p[1.0] * (1 + OPTIMUM_RTOL)
    assert e[1.0] <= e[0.0] * (1 + OPTIMUM_RTOL)


def test_alpha_references_planned_when_not_asked(robot):
    study = alpha_study(alphas=(0.0,), robot=robot, max_iterations=3)
    assert study.perturbation_reference.alpha == 1.0
    assert study.energy_ratio == (1.0,)
    assert study.perturbation_ratio[0] == study.cases[0].J_phi / study.perturbation_reference.J_phi


def test_bad_arguments():
    with pytest.raises(PlannerArgumentError, match="counts"):
        via_point_study(counts=(1, 1))
    with pytest.raises(PlannerArgumentError, match="counts"):
        via_point_study(counts=(-1,))
    with pytest.raises(PlannerArgumentError, match="alphas"):
        alpha_study(alphas=(0.5, 1.5))
    with pytest.raises(PlannerArgumentError, match="methods"):
        method_comparison(methods=())
    with pytest.raises(UnknownMethodError, match="three-step") as error:  # before anything is planned
        method_comparison(methods=("none", "three-step"))
    assert error.value.known == tuple(METHODS)


def test_compared_methods_come_from_the_registry():
    assert studies.COMPARED_METHODS == ("none", "two-step", "one-step")
    assert set(studies.COMPARED_METHODS) <= set(METHODS)


def test_method_comparison_on_one_travel(robot, via: ViaPointStudy):
    comparison = method_comparison("study", methods=("none", "one-step"), robot=robot)
    assert comparison.methods == ("none", "one-step")
    none, one = (comparison.case(m) for m in comparison.methods)
    assert none.J == pytest.approx(1.0, abs=1e-12) and none.iterations == 0
    assert one.J <= none.J * (1 + DENSE_RTOL)
    # one travel: step 1 has nothing to optimise and step 2 is the 1-step problem from the same start
    two = via.cases[via.counts.index(1)]  # the study mission, two-step, n_vp = 1, alpha = 0.5
    assert one.J == pytest.approx(two.J, rel=1e-9)
    for case in comparison.cases:
        assert case.least_ground_clearance > 0 and case.least_singularity_margin > 0
        assert case.peak_thrust > 0 and case.peak_rotor_speed > 0
    rows = comparison.rows()
    assert [r["method"] for r in rows] == list(comparison.methods)
    assert rows[0]["J_e/J_e0"] == 1.0


def test_format_value():
    assert format_value(1.234567) == "1.235"
    assert format_value(1.234567, digits=6) == "1.23457"
    assert format_value(3) == "3"
    assert format_value(True) == "yes" and format_value(np.bool_(False)) == "no"
    assert format_value(None) == "-"
    assert format_value("two-step") == "two-step"


def test_table_contains_every_number(via: ViaPointStudy, alpha: AlphaStudy):
    for study in (via, alpha):
        rows = study.rows()
        text = format_table(rows)
        lines = text.splitlines()
        assert len(lines) == len(rows) + 2  # header, rule, one line per row
        for row, line in zip(rows, lines[2:], strict=True):
            for key, value in row.items():
                assert format_value(value) in line, (key, value, line)
        for key in rows[0]:
            assert key in lines[0]


def test_table_of_given_rows():
    rows = [{"x": 0.000123456, "n": 12, "ok": True, "name": "a"},
            {"x": 98765.4321, "ok": False, "name": "bb"}]
    text = format_table(rows, digits=3)
    for value in ("0.000123", "12", "yes", "9.88e+04", "no", "bb"):
        assert value in text
    assert text.splitlines()[3].split()[1] == "-"  # missing key
    assert format_table([]) == ""


def test_case_to_dict_is_json(via: ViaPointStudy):
    doc = studies.studies_document(via=via)
    text = json.dumps(studies._json_safe(doc))
    back = json.loads(text)
    assert back["via_points"]["counts"] == [0, 1]
    assert back["via_points"]["energy_ratio"][0] == 1.0
    assert set(back["via_points"]["cases"][0]) == {f.name for f in dataclasses.fields(Case)}
    assert studies._json_safe({"a": [math.nan]}) == {"a": [None]}


def test_figures_written(tmp_path, via: ViaPointStudy, alpha: AlphaStudy):
    written = write_study_figures(tmp_path, via=via, alpha=alpha)
    assert [p.name for p in written] == ["via_points.png", "alpha.png"]
    for p in written:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
