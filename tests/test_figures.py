"""Tests of fpr.views.figures (every module of the package): the PNG files, what the figures draw, and the
input checks.
"""

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import fpr
from fpr.model.inverse_dynamics import inverse_dynamics
from fpr.robots.prototype import prototype_joints
from fpr.views import figures
from fpr.views.figures import planning, robot_info, simulation, studies
from planners.optimize import SampledPlan
from planners.trajectory.polynomial import PiecewisePolynomial, stop_points

RATE = 50.0  # sampling rate of the test plans [Hz]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
S0 = [0.0, 0.0, 5 * np.pi / 4, np.pi / 2]
SQUARE = [S0, [1.0, 0.0, 5 * np.pi / 4, np.pi / 2], [1.0, 1.0, 5 * np.pi / 4, np.pi / 2],
          [0.0, 1.0, 5 * np.pi / 4, np.pi / 2], S0]
PROTOTYPE_XI = [[-0.84, 1.68], [-0.14, 0.87], [0.23, 1.12]]


Sampled = SampledPlan  # the object the planner hands to the figures


def _sampled(robot, trajectory: PiecewisePolynomial, is_way, label: str) -> Sampled:
    t, motion = trajectory.sample(RATE)
    return Sampled(label, t, motion, inverse_dynamics(robot, motion), np.array(trajectory.knots),
                   np.asarray(is_way, dtype=bool), np.array(trajectory.points))


def _with_via_points(trajectory: PiecewisePolynomial) -> tuple[PiecewisePolynomial, list[bool]]:
    """The same motion with one via point in the middle of every segment (is_way False there)."""
    points, durations, is_way = [], [], []
    for k, duration in enumerate(trajectory.durations):
        points += [trajectory.points[k], trajectory.evaluate(trajectory.knots[k] + duration / 2)[:, 0, :]]
        durations += [duration / 2, duration / 2]
        is_way += [True, False]
    return PiecewisePolynomial(np.array(points + [trajectory.points[-1]]), durations), is_way + [True]


def _plans(robot, positions, duration: float) -> tuple[Sampled, Sampled]:
    """(plan flying through the way points with one via point per segment, stop-at-way-points reference)."""
    positions = np.asarray(positions, dtype=float)
    durations = [duration] * (len(positions) - 1)
    reference = PiecewisePolynomial(stop_points(positions), durations)
    flying = np.array(reference.points)
    flying[1:-1, 1] = (positions[2:] - positions[:-2]) / (2 * duration)  # fly through, do not stop
    plan, is_way = _with_via_points(PiecewisePolynomial(flying, durations))
    return (_sampled(robot, plan, is_way, "optimised (two-step)"),
            _sampled(robot, reference, [True] * len(positions), "stop at way points"))


@pytest.fixture(scope="module")
def fpr_case():
    robot = fpr.load("fpr")
    return (robot, *_plans(robot, SQUARE, 3.0))


@pytest.fixture(scope="module")
def prototype_case():
    robot = fpr.load("prototype")
    return (robot, *_plans(robot, PROTOTYPE_XI, 4.0))


def _assert_png(path: Path, width_px: int | None = None) -> None:
    from matplotlib.image import imread

    assert path.is_file(), path
    assert path.read_bytes()[:8] == PNG_MAGIC, f"{path} is not a PNG file"
    image = imread(path)
    assert image.ndim == 3 and image.shape[0] > 0 and image.shape[1] > 0
    if width_px is not None:
        assert image.shape[1] == width_px  # figure width [inch] * STYLE["dpi"]
    rgb = np.round(image[..., :3] * 255).astype(np.uint32)
    colours = np.unique(rgb[..., 0] << 16 | rgb[..., 1] << 8 | rgb[..., 2])
    assert len(colours) > 10, f"{path} is nearly one flat colour ({len(colours)} colours)"


def _limit_values(ax) -> list[float]:
    """y (horizontal) or x (vertical) of the limit lines of an axes."""
    out = []
    for line in ax.get_lines():
        if line.get_gid() == figures.LIMIT_LABEL:
            x, y = (np.asarray(v, dtype=float) for v in line.get_data())
            out.append(float(x[0]) if x[0] == x[-1] and y[0] != y[-1] else float(y[0]))
    return sorted(out)


def _legend_texts(ax) -> list[str]:
    legend = ax.get_legend()
    return [] if legend is None else [t.get_text() for t in legend.get_texts()]


# --------------------------------------------------------------------------------- cumulative_integral
def test_cumulative_integral_of_t_squared():
    t = np.linspace(0.0, 2.0, 2001)
    out = figures.cumulative_integral(t, t**2)
    assert out[0] == 0.0
    # trapezoid error on [0, t]: t h^2 f''/12 = t * 1e-6 / 6
    np.testing.assert_allclose(out, t**3 / 3, rtol=0, atol=2.0 / 6 * 1e-6 + 1e-12)
    assert out[-1] == pytest.approx(8 / 3, rel=1e-6)


def test_cumulative_integral_is_exact_for_a_linear_function_on_an_uneven_grid():
    t = np.array([0.0, 0.1, 0.15, 0.7, 1.0, 1.0, 2.5])  # repeated time: a zero step
    values = np.stack([3 * t + 1, -t], axis=1)  # two columns at once
    out = figures.cumulative_integral(t, values)
    np.testing.assert_allclose(out, np.stack([1.5 * t**2 + t, -0.5 * t**2], axis=1), rtol=0, atol=1e-13)
    assert out[-1] == pytest.approx(np.trapezoid(values, t, axis=0), rel=1e-12)


@pytest.mark.parametrize("t, values, match", [
    ([0.0, 1.0, 2.0], [1.0, 2.0], "values.shape"),
    ([[0.0, 1.0]], [1.0, 2.0], "t.shape"),
    ([0.0, 2.0, 1.0], [1.0, 2.0, 3.0], "decreases"),
    ([0.0, 1.0], [1.0, np.nan], "NaN"),
])
def test_cumulative_integral_rejects_bad_input(t, values, match):
    with pytest.raises(ValueError, match=match):
        figures.cumulative_integral(t, values)


# ------------------------------------------------------------------------------------------ plan_figures
@pytest.mark.parametrize("case, with_reference", [("fpr_case", True), ("prototype_case", False)])
def test_plan_figures_writes_valid_pngs(case, with_reference, request, tmp_path):
    robot, plan, reference = request.getfixturevalue(case)
    out_dir = tmp_path / "nested" / robot.name
    paths = figures.plan_figures(out_dir, robot, plan, reference if with_reference else None)
    assert [p.name for p in paths] == [f"{n}.png" for n in figures.PLAN_FIGURES]
    assert sorted(out_dir.iterdir()) == sorted(paths)
    for path in paths:
        _assert_png(path, width_px=round(figures.STYLE["width"] * figures.STYLE["dpi"]))


def test_fpr_coordinates_figure_has_units_and_bounds(fpr_case):
    robot, plan, reference = fpr_case
    fig = planning._coordinates_figure(robot, plan, reference)
    m = robot.margins.angle
    assert len(fig.axes) == 4
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels[0].endswith("[m]") and labels[1].endswith("[m]")
    assert labels[2].endswith("[rad]") and "varphi" in labels[2] and "q_{21}" in labels[3]
    assert fig.axes[-1].get_xlabel() == "t [s]"
    assert _limit_values(fig.axes[0]) == _limit_values(fig.axes[1]) == []  # y, z have no bound
    np.testing.assert_allclose(_limit_values(fig.axes[2]), [np.pi + m, 2 * np.pi - m])
    np.testing.assert_allclose(_limit_values(fig.axes[3]), [m, np.pi - m])
    assert figures.LIMIT_LABEL in _legend_texts(fig.axes[2])
    expected = {"optimised (two-step)", "stop at way points", "way point", "via point"}
    assert expected <= set(_legend_texts(fig.axes[0]))
    # the plan's phi is drawn against t, and the knot lines sit at the plan's knots
    drawn = next(line for line in fig.axes[2].get_lines() if line.get_label() == plan.label)
    np.testing.assert_array_equal(drawn.get_xdata(), plan.t)
    np.testing.assert_array_equal(drawn.get_ydata(), plan.motion[0, :, 2])
    knots = sorted(float(line.get_xdata()[0]) for line in fig.axes[0].get_lines() if line.get_gid() == "knot")
    np.testing.assert_allclose(knots, plan.knots)


def test_prototype_coordinates_figure_bounds(prototype_case):
    robot, plan, _ = prototype_case
    fig = planning._coordinates_figure(robot, plan)
    m = robot.margins.angle
    assert [ax.get_ylabel() for ax in fig.axes] == [r"$q_1$ [rad]", r"$q_2$ [rad]"]
    np.testing.assert_allclose(_limit_values(fig.axes[0]), [-(np.pi / 2 - m), np.pi / 2 - m])
    np.testing.assert_allclose(_limit_values(fig.axes[1]), [m, np.pi - m])


def test_energy_curve_ends_at_the_trapezoid_of_the_power(fpr_case):
    robot, plan, reference = fpr_case
    fig = planning._energy_figure(robot, plan, reference)
    (ax,) = fig.axes
    assert ax.get_ylabel() == "$J_e$ [J]" and ax.get_xlabel() == "t [s]"
    for sampled in (plan, reference):
        curve = next(line for line in ax.get_lines() if line.get_gid() == sampled.label).get_ydata()
        expected = np.trapezoid(sampled.inputs.power.sum(axis=1), sampled.t)
        assert expected > 0
        assert curve[-1] == pytest.approx(expected, rel=1e-9)
        assert curve[0] == 0 and np.all(np.diff(curve) >= 0)  # a cumulative integral of |power|


def test_perturbation_curve_ends_at_the_trapezoid_of_the_squared_roll_rates(prototype_case):
    robot, plan, _ = prototype_case
    (ax,) = planning._perturbation_figure(robot, plan).axes
    assert ax.get_ylabel().endswith("[rad$^2$/s]")
    curve = next(line for line in ax.get_lines() if line.get_gid() == plan.label).get_ydata()
    assert curve[-1] == pytest.approx(np.trapezoid((plan.inputs.roll_rate**2).sum(axis=1), plan.t), rel=1e-9)


@pytest.mark.parametrize("case, n_drones", [("fpr_case", 2), ("prototype_case", 1)])
def test_per_drone_figures(case, n_drones, request):
    robot, plan, reference = request.getfixturevalue(case)
    m = robot.margins.angle
    thrust = planning._thrust_figure(robot, plan, reference)
    assert len(thrust.axes) == n_drones
    assert all(ax.get_ylabel() == f"$|F_{i + 1}|$ [N]" for i, ax in enumerate(thrust.axes))
    np.testing.assert_array_equal(thrust.axes[-1].get_lines()[-1].get_ydata(), reference.inputs.thrust[:, -1])
    roll = planning._roll_figure(robot, plan, reference)
    for ax in roll.axes:
        assert ax.get_ylabel().endswith("[rad]")
        np.testing.assert_allclose(_limit_values(ax), [-(np.pi / 2 - m), np.pi / 2 - m])
    rotors = planning._rotor_speeds_figure(robot, plan, reference)
    w_max = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    for ax in rotors.axes:
        assert ax.get_ylabel().endswith("[rad/s]")
        np.testing.assert_allclose(_limit_values(ax), [0.0, w_max])
        assert {f"rotor {k}" for k in range(1, 5)} | {reference.label, "limit"} == set(_legend_texts(ax))


def test_fpr_path_figure(fpr_case):
    robot, plan, reference = fpr_case
    (ax,) = planning._path_figure(robot, plan, reference).axes
    length = robot.link_length
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("y [m]", "z [m]")
    assert ax.get_aspect() == 1.0
    assert _limit_values(ax) == pytest.approx([-length + robot.margins.ground])
    ground = [line for line in ax.get_lines() if line.get_gid() == "ground"]
    assert len(ground) == 1 and ground[0].get_ydata()[0] == pytest.approx(-length)
    lines = {line.get_gid(): line for line in ax.get_lines() if line.get_label().startswith("optimised")}
    np.testing.assert_array_equal(lines["main"].get_xydata(), plan.motion[0, :, :2])
    r2 = next(line for line in ax.get_lines() if line.get_label() == f"{plan.label}: r2 (drone 2 joint)")
    np.testing.assert_allclose(r2.get_xydata(), plan.inputs.joint_position[:, 1], atol=1e-12)
    way = next(line for line in ax.get_lines() if line.get_gid() == "way")
    via = next(line for line in ax.get_lines() if line.get_gid() == "via")
    assert len(way.get_xdata()) == plan.is_way.sum() == 5 and len(via.get_xdata()) == 4
    assert via.get_markerfacecolor() == "none" and way.get_markerfacecolor() != "none"
    np.testing.assert_allclose(way.get_xydata(), np.array(SQUARE)[:, :2])


def test_prototype_path_figure(prototype_case):
    robot, plan, reference = prototype_case
    (ax,) = planning._path_figure(robot, plan, reference).axes
    length, margin = robot.link_length, robot.margins.ground
    assert _limit_values(ax) == pytest.approx(sorted([-length + margin, margin]))  # ground and fixed point
    joints = prototype_joints(plan.motion[0], length)
    drone = next(line for line in ax.get_lines() if line.get_label() == f"{plan.label}: drone joint")
    elbow = next(line for line in ax.get_lines() if line.get_label() == f"{plan.label}: elbow joint")
    np.testing.assert_allclose(drone.get_xydata(), joints[:, 1], atol=1e-12)
    np.testing.assert_allclose(elbow.get_xydata(), joints[:, 0], atol=1e-12)
    way = next(line for line in ax.get_lines() if line.get_gid() == "way")
    np.testing.assert_allclose(way.get_xydata(), prototype_joints(np.array(PROTOTYPE_XI), length)[:, 1])
    fixed = next(line for line in ax.get_lines() if line.get_gid() == "fixed point")
    np.testing.assert_array_equal(fixed.get_xydata(), [[0.0, 0.0]])


def test_plan_figures_rejects_a_plan_of_the_other_robot(fpr_case, prototype_case, tmp_path):
    robot, _, _ = fpr_case
    _, prototype_plan, _ = prototype_case
    with pytest.raises(ValueError, match=r"plan\.motion\.shape"):
        figures.plan_figures(tmp_path / "out", robot, prototype_plan)
    assert not (tmp_path / "out").exists()  # nothing written before the check


def test_plan_figures_rejects_bad_plans(fpr_case, tmp_path):
    robot, plan, reference = fpr_case
    with pytest.raises(ValueError, match=r"reference\.is_way\.shape"):
        figures.plan_figures(tmp_path, robot, plan, replace(reference, is_way=reference.is_way[:-1]))
    with pytest.raises(ValueError, match="at least 2"):
        figures.plan_figures(tmp_path, robot, replace(plan, t=plan.t[:1]))
    without_knots = SimpleNamespace(**{k: v for k, v in vars(plan).items() if k != "knots"})
    with pytest.raises(ValueError, match="no attribute 'knots'"):
        figures.plan_figures(tmp_path, robot, without_knots)
    with pytest.raises(ValueError, match=r"plan\.inputs has no attribute 'rotor_speed'"):
        figures.plan_figures(tmp_path, robot, replace(plan, inputs=SimpleNamespace(**{
            k: v for k, v in vars(plan.inputs).items() if k != "rotor_speed"})))
    with pytest.raises(ValueError, match=r"is not a robot: pass fpr\.load"):
        figures.plan_figures(tmp_path, not_a_robot(), plan)


def not_a_robot():
    """An object with a robot's name but no kind: the figures ask the kind, never the name."""

    class Other:
        name = "fpr"

    return Other()


# ------------------------------------------------------------------------------------- parameter studies
def test_via_point_study_figure(tmp_path):
    energy, perturbation = [1.0, 0.8, 0.7, 0.65, 0.6], [1.0, 0.5, 0.3, 0.25, 0.2]
    path = figures.via_point_study_figure(tmp_path / "studies" / "via.png", range(5), energy, perturbation)
    assert path == tmp_path / "studies" / "via.png"
    _assert_png(path)
    fig = studies._via_point_study([0, 1, 2, 3, 4], energy, perturbation)
    for ax, ratios in zip(fig.axes, (energy, perturbation), strict=True):
        assert ax.get_ylabel().endswith("[-]") and ax.get_xlabel().endswith("[-]")
        np.testing.assert_allclose([bar.get_height() for bar in ax.patches], ratios)


def test_alpha_study_figure(tmp_path):
    alphas = [1.0, 0.0, 0.3, 0.6, 0.9]
    energy, perturbation = [0.7, 1.0, 0.9, 0.8, 0.75], [1.0, 0.3, 0.4, 0.6, 0.9]
    path = figures.alpha_study_figure(tmp_path / "alpha.png", alphas, energy, perturbation)
    _assert_png(path)
    fig = studies._alpha_study(alphas, energy, perturbation)
    (line,) = fig.axes[0].get_lines()
    np.testing.assert_allclose(line.get_xdata(), [0.0, 0.3, 0.6, 0.9, 1.0])  # sorted by alpha
    np.testing.assert_allclose(line.get_ydata(), [1.0, 0.9, 0.8, 0.75, 0.7])
    assert line.get_marker() == "o"
    assert "alpha=1" in fig.axes[1].get_ylabel()


@pytest.mark.parametrize("call, args, match", [
    ("via_point_study_figure", ([0, 1, 2], [1.0, 0.9], [1.0, 0.5, 0.4]), "mismatched lengths"),
    ("via_point_study_figure", ([0, -1], [1.0, 0.9], [1.0, 0.5]), "integers >= 0"),
    ("via_point_study_figure", ([0, 1.5], [1.0, 0.9], [1.0, 0.5]), "integers >= 0"),
    ("via_point_study_figure", ([], [], []), "k >= 1"),
    ("alpha_study_figure", ([0.0, 1.2], [1.0, 0.9], [1.0, 0.5]), r"\[0, 1\]"),
    ("alpha_study_figure", ([0.0, 1.0], [1.0, np.inf], [1.0, 0.5]), "NaN or inf"),
    ("alpha_study_figure", ([0.0, 1.0], [1.0, 0.9], [1.0]), "mismatched lengths"),
])
def test_study_figures_reject_bad_input(call, args, match, tmp_path):
    with pytest.raises(ValueError, match=match):
        getattr(figures, call)(tmp_path / "x.png", *args)
    assert not (tmp_path / "x.png").exists()


def test_study_figures_want_a_png_name(tmp_path):
    with pytest.raises(ValueError, match="'.png'"):
        figures.alpha_study_figure(tmp_path / "alpha.pdf", [0.0, 1.0], [1.0, 0.9], [1.0, 0.5])


def test_matplotlib_is_lazy_and_pyplot_untouched(tmp_path):
    code = (
        "import sys\n"
        "import fpr.views.figures as f\n"
        "assert 'matplotlib' not in sys.modules, 'matplotlib imported with fpr.views.figures'\n"
        "import matplotlib\n"
        "def rc():  # raw values: reading rcParams['backend'] would resolve (and import) a backend\n"
        "    return dict(dict.items(matplotlib.rcParams))\n"
        "before = rc()\n"
        f"f.via_point_study_figure({str(tmp_path / 'v.png')!r}, [0, 1], [1.0, 0.8], [1.0, 0.4])\n"
        "assert 'matplotlib.pyplot' not in sys.modules, 'pyplot imported'\n"
        "assert rc() == before, 'global rcParams (or the backend choice) changed'\n"
    )
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=str(root))
    result = subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    _assert_png(tmp_path / "v.png")


# ------------------------------------------------------------------------------------------ rotor forces
@pytest.mark.parametrize("case", ["fpr_case", "prototype_case"])
def test_rotor_forces_figure_draws_c_t_w_squared_against_the_limits(case, request):
    robot, plan, reference = request.getfixturevalue(case)
    fig = planning._rotor_forces_figure(robot, plan, reference)
    c_t = robot.rotor_constants.thrust_coefficient
    upper = c_t * (robot.rotor_constants.max_speed - robot.margins.rotor_speed) ** 2
    assert upper == pytest.approx(6.25, rel=1e-3)  # 750 rad/s (the seed's 9 N are at 900 rad/s)
    assert len(fig.axes) == robot.n_drones
    for i, ax in enumerate(fig.axes):
        assert ax.get_ylabel() == rf"$c_T \omega_{{{i + 1},j}}^2$ [N]" and ax.get_xlabel() in ("", "t [s]")
        np.testing.assert_allclose(_limit_values(ax), [0.0, upper])
        rotor_2 = next(line for line in ax.get_lines() if line.get_label() == "rotor 2")
        expected = c_t * plan.inputs.rotor_speed_squared[:, i, 1]
        np.testing.assert_allclose(rotor_2.get_ydata(), expected, rtol=1e-12)
    assert fig.axes[-1].get_xlabel() == "t [s]"


# ------------------------------------------------------------------------------------- simulation figures
def _log(robot, sampled, offset: float = 0.0):
    """A SimulationLog that tracks ``sampled``, with ``offset`` sin(t) on the first planning coordinate.

    The out-of-plane coordinates get the same offset. Stands in for fpr.sim.closed_loop.simulate (seconds).
    """
    from fpr.sim.closed_loop import SimulationLog

    inputs = sampled.inputs
    q, v, _ = inputs.full_state(robot)
    t = sampled.t
    wobble = offset * np.sin(t)
    first = robot.index[robot.layout.chain[0]]
    q[:, first] += wobble
    v[:, first] += offset * np.cos(t)
    for name in ("x", "psi", "theta"):
        if name in robot.index:
            q[:, robot.index[name]] = wobble
    n = t.size
    limit = robot.rotor_constants.max_speed - robot.margins.rotor_speed
    return SimulationLog(robot.name, tuple(robot.layout.coordinates), tuple(robot.layout.chain), t, q, v,
                         sampled.motion[:3], inputs.roll, inputs.roll + 0.01, inputs.rotor_speed,
                         inputs.rotor_speed,
                         inputs.thrust, inputs.torque, np.zeros((n, robot.n_drones, 4), dtype=bool),
                         inputs.joint_position[..., 1] + robot.hinge_offset, np.zeros(n),
                         robot.rotor_constants.max_speed, limit, 1.0)


@pytest.fixture(scope="module")
def fpr_log(fpr_case):
    robot, plan, _ = fpr_case
    return _log(robot, plan, offset=0.01)


@pytest.fixture(scope="module")
def prototype_log(prototype_case):
    robot, plan, _ = prototype_case
    return _log(robot, plan, offset=0.01)


def _line(ax, gid: str):
    return next(line for line in ax.get_lines() if line.get_gid() == gid)


@pytest.mark.parametrize("case, log", [("fpr_case", "fpr_log"), ("prototype_case", "prototype_log")])
def test_simulation_figures_write_valid_pngs(case, log, request, tmp_path):
    robot, plan, _ = request.getfixturevalue(case)
    paths = figures.simulation_figures(tmp_path / "sim", robot, request.getfixturevalue(log), plan)
    assert [p.name for p in paths] == [f"{n}.png" for n in figures.SIMULATION_FIGURES]
    for path in paths:
        _assert_png(path)


def test_sim_path_overlays_plan_and_simulation(fpr_case, fpr_log, prototype_case, prototype_log):
    robot, plan, _ = fpr_case
    (ax,) = simulation._sim_path(robot, fpr_log, plan).axes
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("y [m]", "z [m]")
    assert _limit_values(ax) == pytest.approx([-robot.link_length + robot.margins.ground])
    np.testing.assert_allclose(_line(ax, "planned").get_xydata(), plan.motion[0, :, :2])
    simulated = plan.motion[0, :, :2] + np.stack([0.01 * np.sin(plan.t), 0 * plan.t], axis=1)
    np.testing.assert_allclose(_line(ax, "simulated").get_xydata(), simulated, atol=1e-12)
    assert len(_line(ax, "way").get_xdata()) == 5 and len(_line(ax, "via").get_xdata()) == 4
    robot, plan, _ = prototype_case
    (ax,) = simulation._sim_path(robot, prototype_log, plan).axes
    drone_joint = plan.inputs.joint_position[:, 0]
    np.testing.assert_allclose(_line(ax, "planned").get_xydata(), drone_joint, atol=1e-12)
    assert _limit_values(ax) == pytest.approx(sorted([-robot.link_length + robot.margins.ground,
                                                      robot.margins.ground]))


@pytest.mark.parametrize("case, log", [("fpr_case", "fpr_log"), ("prototype_case", "prototype_log")])
def test_sim_coordinates_have_bounds_and_errors(case, log, request):
    robot, plan, _ = request.getfixturevalue(case)
    fig = simulation._sim_coordinates(robot, request.getfixturevalue(log))
    specs = robot_info._coordinate_axes(robot)
    assert len(fig.axes) == 2 * len(specs)
    for j, (label, bounds) in enumerate(specs):
        ax, ax_err = fig.axes[2 * j], fig.axes[2 * j + 1]
        assert ax.get_ylabel() == label and ax_err.get_ylabel().endswith(label[label.index("["):])
        assert "error" in ax_err.get_ylabel()
        np.testing.assert_allclose(_limit_values(ax), sorted(bounds) if bounds else [])
        np.testing.assert_array_equal(_line(ax, "planned").get_ydata(), plan.motion[0, :, j])
        expected = 0.01 * np.sin(plan.t) if j == 0 else np.zeros_like(plan.t)
        np.testing.assert_allclose(_line(ax_err, "error").get_ydata(), expected, atol=1e-12)
    assert [ax.get_xlabel() for ax in fig.axes[-2:]] == ["t [s]", "t [s]"]


def test_sim_out_of_plane_roll_and_heights(fpr_case, fpr_log, prototype_case, prototype_log):
    robot, plan, _ = fpr_case
    fig = simulation._sim_out_of_plane(robot, fpr_log)
    assert [ax.get_ylabel() for ax in fig.axes] == ["x [m]", r"$\theta$ [rad]", r"$\psi$ [rad]"]
    np.testing.assert_allclose(_line(fig.axes[0], "simulated").get_ydata(), 0.01 * np.sin(plan.t))
    assert _line(fig.axes[0], "planned").get_ydata()[0] == 0.0
    proto_robot, proto_plan, _ = prototype_case
    fig = simulation._sim_out_of_plane(proto_robot, prototype_log)
    assert [ax.get_ylabel() for ax in fig.axes] == [r"$\theta$ [rad]", r"$\psi$ [rad]"]  # no x: pinned

    bound = np.pi / 2 - robot.margins.angle
    roll = simulation._sim_roll(robot, fpr_log)
    for i, ax in enumerate(roll.axes):
        assert ax.get_ylabel() == rf"$\varphi_{i + 1}$ [rad]"
        np.testing.assert_allclose(_limit_values(ax), [-bound, bound])
        np.testing.assert_allclose(_line(ax, "simulated").get_ydata(), plan.inputs.roll[:, i])
        np.testing.assert_allclose(_line(ax, "desired").get_ydata(), plan.inputs.roll[:, i] + 0.01)

    ground = -robot.link_length + robot.margins.ground
    heights = simulation._sim_heights(robot, fpr_log)
    assert [ax.get_ylabel() for ax in heights.axes] == ["$z_1$ [m]", "$z_2$ [m]"]
    for i, ax in enumerate(heights.axes):
        assert _limit_values(ax) == pytest.approx([ground])
        np.testing.assert_allclose(_line(ax, "planned").get_ydata(), plan.inputs.joint_position[:, i, 1])
        np.testing.assert_allclose(_line(ax, "com").get_ydata(), fpr_log.drone_height[:, i])
    heights = simulation._sim_heights(proto_robot, prototype_log)
    assert [ax.get_ylabel() for ax in heights.axes] == ["$z_{j2}$ [m]", "$z_{j3}$ [m]"]  # Fig. 3.46-3.47
    elbow = prototype_joints(proto_plan.motion[0], proto_robot.link_length)[:, 0, 1]
    np.testing.assert_allclose(_line(heights.axes[0], "planned").get_ydata(), elbow, atol=1e-12)
    assert all(_limit_values(ax) == pytest.approx([-proto_robot.link_length + proto_robot.margins.ground])
               for ax in heights.axes)


@pytest.mark.parametrize("case, log", [("fpr_case", "fpr_log"), ("prototype_case", "prototype_log")])
def test_sim_rotor_figures_limits_and_saturation(case, log, request):
    robot, plan, _ = request.getfixturevalue(case)
    log = request.getfixturevalue(log)
    c_t, w_max = robot.rotor_constants.thrust_coefficient, robot.rotor_constants.max_speed
    upper = w_max - robot.margins.rotor_speed
    speeds = simulation._sim_rotor_speeds(robot, log, plan)
    forces = simulation._sim_rotor_forces(robot, log, plan)
    for i, (ax_w, ax_f) in enumerate(zip(speeds.axes, forces.axes, strict=True)):
        assert ax_w.get_ylabel().endswith("[rad/s]") and ax_f.get_ylabel().endswith("[N]")
        np.testing.assert_allclose(_limit_values(ax_w), [0.0, upper])
        np.testing.assert_allclose(_limit_values(ax_f), [0.0, c_t * upper**2])
        assert _line(ax_w, "saturation").get_ydata()[0] == w_max
        assert _line(ax_f, "saturation").get_ydata()[0] == pytest.approx(c_t * w_max**2)
        simulated = [line for line in ax_f.get_lines() if line.get_gid() == "simulated"]
        planned = [line for line in ax_f.get_lines() if line.get_gid() == "planned"]
        assert len(simulated) == len(planned) == 4
        np.testing.assert_allclose(simulated[2].get_ydata(), c_t * log.speed[:, i, 2] ** 2, rtol=1e-12)
        assert {"rotor 1", "planned", "limit"} <= set(_legend_texts(ax_f))
    without_plan = simulation._sim_rotor_speeds(robot, log)
    assert len(without_plan.axes[0].get_lines()) == 4 + 3  # no planned lines


@pytest.mark.parametrize("case", ["fpr_case", "prototype_case"])
def test_simulated_indices_of_a_perfect_tracking_equal_the_planned_ones(case, request):
    robot, plan, _ = request.getfixturevalue(case)
    perfect = _log(robot, plan)
    energy, perturbation = figures.simulated_indices(robot, perfect)
    assert energy[-1] == pytest.approx(np.trapezoid(plan.inputs.power.sum(axis=1), plan.t), rel=1e-9)
    squared_rates = (plan.inputs.roll_rate**2).sum(axis=1)
    assert perturbation[-1] == pytest.approx(np.trapezoid(squared_rates, plan.t), rel=1e-9)
    fig = simulation._sim_energy(robot, perfect, plan)
    assert [ax.get_ylabel() for ax in fig.axes] == ["$J_e$ [J]", r"$J_\varphi$ [rad$^2$/s]"]
    for ax, curve in zip(fig.axes, (energy, perturbation), strict=True):
        np.testing.assert_allclose(_line(ax, "simulated").get_ydata(), curve)
        np.testing.assert_allclose(_line(ax, "planned").get_ydata(), curve, rtol=1e-9, atol=1e-12)


def test_simulation_figures_reject_a_log_of_the_other_robot(fpr_case, prototype_log, tmp_path):
    robot, plan, _ = fpr_case
    with pytest.raises(ValueError, match="robot_name='prototype'"):
        figures.simulation_figures(tmp_path / "out", robot, prototype_log)
    with pytest.raises(ValueError, match="SimulationLog"):
        figures.simulation_figures(tmp_path / "out", robot, SimpleNamespace(t=plan.t))
    assert not (tmp_path / "out").exists()


# -------------------------------------------------------------------------------------------- figure_set
@pytest.fixture(scope="module")
def square_stop():
    """The stop-at-way-points PlanResult of the square mission (planning it takes ~0.1 s)."""
    from planners.missions.mission import load_mission
    from planners.optimize import plan

    return plan(load_mission("square"), "none")


def test_figure_set_writes_every_figure(square_stop, tmp_path, monkeypatch):
    def save(fig, path):  # the figures are built as usual; rendering PNGs is tested above (and slow)
        assert fig.axes and fig.get_suptitle().startswith(("Fig.", "Eq.", "Energy"))
        path.write_bytes(PNG_MAGIC)
        return path

    monkeypatch.setattr(planning, "_save", save)
    monkeypatch.setattr(simulation, "_save", save)
    robot = square_stop.robot
    sampled = square_stop.sampled(RATE)
    log = _log(robot, sampled, offset=0.01)
    paths = figures.figure_set(tmp_path / "all", square_stop, log, reference=square_stop, rate=RATE)
    assert tuple(paths) == figures.FIGURE_SET
    assert paths["sim_rotor_forces"] == tmp_path / "all" / "sim_rotor_forces.png"
    written = sorted(p.name for p in (tmp_path / "all").iterdir())
    assert written == sorted(f"{n}.png" for n in figures.FIGURE_SET)
    only_plan = figures.figure_set(tmp_path / "plan", sampled, robot=robot)
    assert tuple(only_plan) == figures.PLAN_FIGURES
    assert all(path.is_file() for path in only_plan.values())


def test_figure_set_checks_before_writing(square_stop, prototype_log, tmp_path):
    with pytest.raises(ValueError, match="robot_name='prototype'"):
        figures.figure_set(tmp_path / "out", square_stop, prototype_log)
    with pytest.raises(ValueError, match="no robot"):
        figures.figure_set(tmp_path / "out", square_stop.sampled(RATE))
    with pytest.raises(ValueError, match="PlanResult or a sampled plan"):
        figures.figure_set(tmp_path / "out", square_stop, reference="none")
    with pytest.raises(ValueError, match="rate"):
        figures.figure_set(tmp_path / "out", square_stop, rate=0.0)
    assert not (tmp_path / "out").exists()
