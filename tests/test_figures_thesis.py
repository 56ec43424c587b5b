"""The figures' conventions: thesis figure numbers in the titles, the limits that apply to the motion shown,
lines that stay visible, legends beside the data, value labels with enough digits, direction and time marks on
paths, no numerical noise presented as a result; and the new views (closed-loop margins, stroboscopic view, GIF).
"""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image
from test_margins import follow

from fpr.model.errors import FigureError
from fpr.sim.margins import margin_series
from fpr.views.figures.chain import chain_animation, chain_points, strobe_figure
from fpr.views.figures.margins import PHYSICAL_LABEL, margins_figure
from fpr.views.figures.planning import _path_figure, _rotor_speeds_figure, _thrust_figure
from fpr.views.figures.robot_info import _applicable_bounds, _title, figure_context
from fpr.views.figures.simulation import NOISE_LEVEL, _sim_out_of_plane
from fpr.views.figures.studies import APPENDIX_FIGURES, _value_labels
from fpr.views.figures.style import LIMIT_LABEL, ROTOR_STYLES
from fpr.views.thesis import Claim, claims_markdown, fmt
from planners.missions.mission import load_mission
from planners.optimize import plan


@pytest.fixture(scope="module")
def study():
    return plan(load_mission("study"), "none")


def test_titles_carry_the_figure_numbers_of_the_motion_shown(study):
    robot = study.robot
    assert _title(robot, "path").startswith("Fig. 3.11")
    with figure_context(APPENDIX_FIGURES["two-step"]):
        assert _title(robot, "path").startswith("Appendix, Fig. 4.12 — ")
        assert _title(robot, "perturbation").startswith("Appendix, Fig. 4.18 — ")
    with figure_context("Singularity crossing (thesis ch. 4)"):
        assert _title(robot, "thrust").startswith("Singularity crossing (thesis ch. 4) — ")
    assert _title(robot, "path").startswith("Fig. 3.11")  # the context is gone


def test_a_crossing_does_not_get_the_bounds_it_crosses_on_purpose():
    bounds = (0.2, np.pi - 0.2)
    q2 = np.array([1.894, 0.5, -0.4, -1.894])
    assert _applicable_bounds(bounds, q2) == bounds  # any other motion: every bound, a violation stays visible
    with figure_context(crossing=True):
        assert _applicable_bounds(bounds, q2) == (np.pi - 0.2,)


def _lines(fig, gid):
    return [line for ax in fig.axes for line in ax.get_lines() if line.get_gid() == gid]


def test_the_thrust_floor_is_drawn_when_there_is_one(study):
    sampled = study.sampled(50.0)
    assert not _lines(_thrust_figure(study.robot, sampled), LIMIT_LABEL)
    with figure_context(min_thrust=7.85):
        floors = _lines(_thrust_figure(study.robot, sampled), LIMIT_LABEL)
    assert floors and all(np.allclose(line.get_ydata(), 7.85) for line in floors)


def test_rotor_lines_differ_in_style_and_legends_sit_beside_the_axes(study):
    fig = _rotor_speeds_figure(study.robot, study.sampled(50.0))
    ax = fig.axes[0]
    rotors = [line for line in ax.get_lines() if line.get_label().startswith("rotor")]
    assert len(rotors) == 4 and len({str(line.get_linestyle()) for line in rotors}) == 4
    assert len(set(ROTOR_STYLES)) == 4
    legend = ax.get_legend()
    fig.canvas.draw()
    assert legend.get_window_extent().x0 >= ax.get_window_extent().x1  # right of the data, not over it


def test_paths_have_direction_and_time_marks(study):
    fig = _path_figure(study.robot, study.sampled(50.0))
    texts = [a for a in fig.axes[0].texts if a.get_gid() == "time mark"]
    arrows = [a for a in fig.axes[0].texts if a.get_gid() == "direction"]
    assert {t.get_text() for t in texts} == {"0 s", "3 s"} and len(arrows) >= 5
    start, end = arrows[0], arrows[-1]  # the arrows point along the motion: from (0, 0) towards (1, 1)
    assert np.linalg.norm(np.subtract(start.xy, [0, 0])) < np.linalg.norm(np.subtract(end.xy, [0, 0]))


def test_value_labels_tell_close_ratios_apart():
    labels = _value_labels([1.0, 0.9996, 0.9991])
    assert len(set(labels)) == 3 and labels[1] != "1" and labels[1].startswith("0.999")
    assert _value_labels([1.0, 0.62, 0.41]) == ["1.000", "0.620", "0.410"]


def test_numerical_noise_is_not_drawn_as_a_result(study):
    log = follow(study)  # x, psi, theta exactly 0
    log.q[:, log.coordinates.index("x")] = 3e-9 * np.sin(np.arange(log.t.size))
    fig = _sim_out_of_plane(study.robot, log)
    ax = fig.axes[0]
    assert ax.get_ylim()[1] == pytest.approx(10 * NOISE_LEVEL)
    assert any(t.get_gid() == "noise" and "3.0e-09" in t.get_text() for t in ax.texts)
    log.q[:, log.coordinates.index("x")] = 0.01 * np.sin(log.t)  # a real motion is drawn as it is
    ax = _sim_out_of_plane(study.robot, log).axes[0]
    assert not [t for t in ax.texts if t.get_gid() == "noise"] and ax.get_ylim()[1] > 0.009


def test_the_margins_figure_draws_both_limits(study, tmp_path):
    log = follow(study)
    series = margin_series(study, log)
    path = margins_figure(tmp_path / "m.png", series, names=["ground_1", "rotor_speed_high_2"])
    assert path.is_file() and path.stat().st_size > 0
    with pytest.raises(FigureError):
        margins_figure(tmp_path / "m.png", series, names=["nope"])
    s = series["ground_1"]
    assert np.allclose(s.physical - s.planning, study.robot.margins.ground)  # the physical line sits m_gd below
    assert PHYSICAL_LABEL == "physical limit"


def test_strobe_and_animation_of_a_log(study, tmp_path):
    log = follow(study, tick=0.02)
    chain = chain_points(study.robot, log.q[:, [log.coordinates.index(c) for c in study.robot.layout.chain]])
    assert chain.shape == (len(log.t), 3, 2)  # FPR: drone joint 1, end-effector, drone joint 2
    assert np.allclose(chain[:, 1], log.q[:, [log.coordinates.index("y"), log.coordinates.index("z")]])
    assert strobe_figure(tmp_path / "s.png", study.robot, log, count=5).stat().st_size > 0
    gif = chain_animation(tmp_path / "a.gif", study.robot, log, fps=4, speed=1.0)
    with Image.open(gif) as frames:
        assert frames.n_frames == 12  # 3 s at 4 frames per simulated second
    with pytest.raises(FigureError):
        chain_animation(tmp_path / "a.avi", study.robot, log)


def test_thesis_table_rounds_and_demands_a_reason():
    assert fmt(557683.9) == "557,684" and fmt(-557683.4) == "-557,683" and fmt(0.50871, 4) == "0.5087"
    assert fmt(13.52, 3, "N") == "13.5 N" and fmt(0.0) == "0" and fmt(True) == "yes"
    assert fmt(3) == "3" and fmt(2.132e-14, 4) == "2.132e-14" and fmt(np.bool_(False)) == "no"
    with pytest.raises(Exception, match="say why"):
        Claim("x", "3.2.5", "-", "-", False)
    table = claims_markdown([Claim("a | b", "Fig. 1", "t", "o", True), Claim("c", "2", "t", "o", False, "because")])
    assert table.count("\n") == 3 and "a \\| b" in table and "**no**" in table and "because" in table
