"""What a new user meets first: the figures of ``python -m fpr.plan --simulate`` and of a campaign, the 3D view in a
notebook, the optional extras, and Python run from the folder above a clone named ``fpr``.
"""

import io
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fpr
from fpr import extras
from fpr.robustness.spec import unit
from fpr.sim.closed_loop import simulate
from fpr.views.figures import figure_set, planning
from fpr.views.figures.campaign import outcomes_figure, success_figure
from fpr.views.figures.style import STYLE, _styled
from fpr.views.scene import view
from planners.missions.mission import load_mission
from planners.optimize import plan

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def square_flown():
    """The square's two-step plan, its stop-at-way-points reference and a short simulation of the plan."""
    mission = load_mission("square")
    result = plan(mission)
    return result, plan(mission, "none"), simulate(result)


def _edges_blank(png: Path, band: int = 2) -> bool:
    """Whether the outer ``band`` pixels of an image are all background (nothing drawn reaches the canvas's edge)."""
    from matplotlib.image import imread

    image = imread(png)[..., :3]
    frame = np.concatenate([image[:band].reshape(-1, 3), image[-band:].reshape(-1, 3),
                            image[:, :band].reshape(-1, 3), image[:, -band:].reshape(-1, 3)])
    return bool(frame.min() >= 0.98)


def test_nothing_of_the_square_mission_figures_is_cut_at_the_canvas_edge(square_flown, tmp_path):
    """Every figure of ``python -m fpr.plan --mission square --simulate``: the outermost pixels are background, and
    every axis label lies inside the canvas (the y labels of coordinates.png were cut at the left edge when the
    layout was made before the saved figure's tick labels were chosen).
    """
    result, reference, log = square_flown
    paths = figure_set(tmp_path, result, log, reference=reference, rate=100.0)
    clipped = [name for name, path in paths.items() if not _edges_blank(path)]
    assert not clipped, f"drawn up to the canvas edge: {clipped}"
    fig = planning._coordinates_figure(result.robot, result.sampled(100.0), reference.sampled(100.0))
    with _styled():
        fig.savefig(io.BytesIO(), dpi=STYLE["dpi"], format="png")
        renderer = fig.canvas.get_renderer()
        for ax in fig.axes:
            box = ax.yaxis.label.get_window_extent(renderer)
            assert box.x0 >= 0 and box.x1 <= fig.bbox.width, (ax.get_ylabel(), box)


def test_the_reference_rotor_curves_each_have_their_rotors_colour(square_flown):
    result, reference, _ = square_flown
    fig = planning._rotor_speeds_figure(result.robot, result.sampled(100.0), reference.sampled(100.0))
    for ax in fig.axes:
        lines = {line.get_gid(): line for line in ax.get_lines() if line.get_gid()}
        for k in range(1, 5):
            ours, theirs = lines[f"rotor {k}"], lines[f"{reference.label}: rotor {k}"]
            assert ours.get_color() == theirs.get_color()
        colours = {lines[f"{reference.label}: rotor {k}"].get_color() for k in range(1, 5)}
        assert len(colours) == 4


def test_the_way_point_times_stay_off_the_reference_path(square_flown):
    """The times of path.png ("0 s, 12 s", "3 s", ...) are placed outside the way points' square: no point of the
    dashed reference path lies inside a label's box.
    """
    result, reference, _ = square_flown
    fig = planning._path_figure(result.robot, result.sampled(100.0), reference.sampled(100.0))
    with _styled():
        fig.savefig(io.BytesIO(), dpi=STYLE["dpi"], format="png")
        renderer = fig.canvas.get_renderer()
        (ax,) = fig.axes
        marks = [t for t in ax.texts if t.get_gid() == "time mark"]
        assert len(marks) == 4
        path = next(line for line in ax.get_lines() if line.get_label().startswith(reference.label) and
                    line.get_gid() == "main")
        y, z = path.get_data()
        t = np.linspace(0.0, 1.0, 50)[:, None]  # the straight sides between the samples, finely
        points = np.column_stack([y, z])
        dense = (points[:-1, None] * (1 - t[None]) + points[1:, None] * t[None]).reshape(-1, 2)
        pixels = ax.transData.transform(dense)
        for mark in marks:
            box = mark.get_window_extent(renderer)
            inside = (pixels[:, 0] >= box.x0) & (pixels[:, 0] <= box.x1) & (pixels[:, 1] >= box.y0) & \
                     (pixels[:, 1] <= box.y1)
            assert not inside.any(), f"{mark.get_text()!r} sits on the reference path"


def _campaign_rows(count: int = 40):
    rng = np.random.default_rng(3)
    rows = []
    for i in range(count):
        error, wind = float(rng.uniform(-0.05, 0.05)), float(rng.uniform(-4.0, 4.0))
        ok = abs(wind) < 3.0
        rows.append({"index": i, "initial_error.y": error, "wind_y": wind, "link_length": 0.8 + 0.01 * i,
                     "success": ok, "error": "", "max_error_y": abs(error) + 0.1 * abs(wind),
                     "max_error_phi": 0.01 * abs(wind), "least_clearance_m": 1.2, "saturated_ticks": 0,
                     "peak_rotor_speed_rad_s": 600.0 + 10.0 * abs(wind)})
    return rows


def test_campaign_axes_have_units_and_tick_labels_that_do_not_overlap():
    rows = _campaign_rows()
    varied = ["initial_error.y", "link_length", "wind_y"]
    for fig in (success_figure(rows, varied), outcomes_figure(rows, ["y", "phi"], 750.0)):
        with _styled():
            fig.savefig(io.BytesIO(), dpi=STYLE["dpi"], format="png")
            renderer = fig.canvas.get_renderer()
            for ax in fig.axes:
                if not ax.get_visible():
                    continue
                label = ax.get_xlabel()
                assert label.endswith("]") and "[" in label, label
                boxes = sorted((t.get_window_extent(renderer) for t in ax.get_xticklabels()
                                if t.get_visible() and t.get_text()), key=lambda b: b.x0)
                boxes = [b for b in boxes if ax.bbox.x0 - 20 <= b.x0 <= ax.bbox.x1 + 20]
                assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:], strict=False)), f"{label}: tick labels overlap"
    assert unit("initial_error.y") == "m" and unit("initial_error.phi") == "rad" and unit("wind_z") == "N"
    assert unit("link_length") == "m" and unit("max_error_q21") == "rad" and unit("model_mass_scale") == "1"


def test_a_3d_view_has_a_short_text_repr():
    """A notebook stores an output's text/plain beside its HTML: the generated dataclass repr held every mesh."""
    scene = view(fpr.load("fpr"))
    text = repr(scene)
    assert len(text) < 300 and text.startswith("SceneView(") and "commands" in text
    assert len(scene._repr_html_()) > 10_000  # the page itself is still all there


def test_a_missing_extra_is_named_with_its_pip_command(monkeypatch):
    monkeypatch.setattr(extras.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(extras.MissingExtraError) as caught:
        extras.require("campaign")
    assert isinstance(caught.value, fpr.FprError) and caught.value.missing == ("distributed", "pyarrow")
    assert str(caught.value).startswith("install the campaign extra: pip install -e '.[campaign]'")


def test_the_campaign_command_without_its_extra_exits_2_with_the_hint(tmp_path):
    """A Python whose ``distributed`` cannot be imported (a shadowing module that fails): exit 2 and one line."""
    shadow = tmp_path / "shadow"
    shadow.mkdir()
    sitecustomize = ("import importlib.util as u\n_find = u.find_spec\n"
                     "u.find_spec = lambda name, *a, **k: None if name == 'distributed' else _find(name, *a, **k)\n")
    (shadow / "sitecustomize.py").write_text(sitecustomize)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(shadow), str(ROOT), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-m", "fpr.campaign", "--runs", "2", "--out", str(tmp_path / "out")],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines()[-1] == ("error: install the campaign extra: pip install -e '.[campaign]' "
                                                    "(missing: distributed)")
    assert "Traceback" not in done.stderr


def test_python_in_the_folder_above_a_clone_named_fpr_imports_the_clone(tmp_path):
    """``cd parent && python -c "import fpr; fpr.load"`` with a clone at parent/fpr: the clone's package, not an
    empty namespace package, and planners from the same clone.
    """
    (tmp_path / "fpr").symlink_to(ROOT, target_is_directory=True)
    code = ("import json, fpr, planners; fpr.load; "
            "print(json.dumps([fpr.__file__, planners.__file__, callable(fpr.load)]))")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    package, planners, loads = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(package).resolve() == ROOT / "fpr" / "__init__.py"
    assert Path(planners).resolve() == ROOT / "planners" / "__init__.py" and loads


def test_a_long_title_wraps_inside_the_canvas(tmp_path):
    """A singularity crossing's titles ran past both edges of its rotor figures; now they wrap."""
    from fpr.views.figures.style import _finish, _new_figure, _save

    with _styled():
        fig, (ax,) = _new_figure(1)
        ax.plot([0, 1], [0, 1], label="a line")
        _finish(fig, "Singularity crossing (thesis ch. 4; cf. Fig. 4.2-4.9) — rotor speeds of the drone of the "
                     "prototype, and some more words so that no canvas could hold it on one line", [ax])
    assert _edges_blank(_save(fig, tmp_path / "long.png"))
