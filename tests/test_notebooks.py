"""The numbered notebooks: committed without outputs, and executed end to end.

Each ``notebooks/NN_*.ipynb`` runs in a fresh ``python3`` kernel (the interpreter of the tests: checked),
in a temporary folder, with ``FPR_NOTEBOOK_QUICK=1`` (the notebooks' coarser settings). A failing cell
fails the test. Then checks run in the notebook's own kernel, on its variables (the planned square is
feasible and better than stopping, the tracking errors are small, ...), and the outputs must hold the
figures and 3D views the notebook promises. Together about a minute on a 2-core machine.

A lost kernel message must not hang the suite (a cell's reply once never came, and the kernel sat idle until
the runner's timeout): every cell has :data:`CELL_TIMEOUT`, and a notebook whose cell times out or whose
kernel dies is run once more from the start in a fresh kernel; a second failure fails the test.
"""

from __future__ import annotations

import copy
import os
import re
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient
from nbclient.exceptions import CellTimeoutError, DeadKernelError

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
#: Per cell [s]: the longest cell of the quick notebooks takes well under a minute on a loaded 2-core machine.
CELL_TIMEOUT = 240
#: Kernel start [s].
STARTUP_TIMEOUT = 120
#: Runs of a notebook whose cell timed out or whose kernel died: the first, and one in a fresh kernel.
ATTEMPTS = 2


@dataclass(frozen=True)
class Expected:
    """What a notebook's outputs must contain, and code run in its kernel after its last cell."""

    images: int  # PNG figures displayed, at least
    html: int  # rich HTML outputs (meshcat views), at least
    checks: str  # Python, asserting on the notebook's variables


EXPECTED = {
    "01_model": Expected(images=0, html=2, checks="""
assert np.allclose(M, M.T) and np.linalg.eigvalsh(M).min() > 0
assert np.abs(ac - expected).max() < 1e-9 * (1 + np.abs(expected).max())  # closed chain = minimal model
assert abs(hover.thrust_vector[0, :, 1].sum() - robot.total_mass * 9.81) < 1e-9
assert np.allclose(prototype_inverse_kinematics(drone_joint, L, "up"), [0.9470, -1.8940], atol=1e-4)
assert len(claims) >= 4 and det_error < 1e-12 and null_residual < 1e-12 and same_point < 1e-3
assert [c.where for c in claims if not c.agree] == ["eq. 3.36, 4.1"]  # the printed signs, explained
"""),
    "02_square_mission": Expected(images=16, html=1, checks="""
from fpr.views.figures import FIGURE_SET
assert result.feasible and reference.feasible and result.J < 0.9 and reference.J == 1.0
assert max(summary["tracking_max"].values()) < 0.01 and summary["saturated_ticks"] == 0
assert tuple(paths) == FIGURE_SET and all(p.is_file() and p.stat().st_size > 0 for p in paths.values())
# closed-loop margins: every planned constraint, none broken; the energy floor is below both motions' J_e
assert set(margins) == set(result.report.constraints) and not broken(margins)
assert abs(energy_floor - robot.total_mass * g * 2.0) < 1e-9 and energy_floor <= result.report.J_e * (1 + 1e-9)
assert energy_floor <= reference.report.J_e * (1 + 1e-9) and len(claims) >= 6
# the table's verdicts follow the numbers, and every disagreement is explained
assert claims[2].agree == (opt["peak_thrust_N"] <= stop["peak_thrust_N"]) and all(c.agree or c.why for c in claims)
assert claims[3].agree == (y_end.max() < 1.05)
# a slider replans: one more via point per side gives a different plan, with more points
before, count = live.result, len(live.history)
assert count >= 1 and before is not None  # the widget planned once when it was built
sliders.children[0].value = 2
assert len(live.history) == count + 1 and live.result is not before and live.history[-1]["via_points"] == 2
assert live.result.trajectory.points.shape[0] > before.trajectory.points.shape[0] and live.result.J != before.J
"""),
    "03_parameter_study": Expected(images=4, html=0, checks="""
assert all(via.feasible) and all(alpha.feasible) and all(c.feasible for c in comparison.cases)
assert via.J_phi[-1] < via.J_phi[0] and via.counts == COUNTS and alpha.alphas == WEIGHTS
assert comparison.case("two-step").J < 1.0 and comparison.case("one-step").J < 1.0
assert len(COUNTS) < 5 and len(written) >= 2 + 2 * 8  # quick mode; both study figures and two plan sets
assert claims[0].agree == (not zero.feasible) and claims[4].agree == (two.J < one.J)
assert climb_floor <= min(via.J_e + alpha.J_e) * (1 + 1e-9) and all(c.agree or c.why for c in claims)
before = live.result
sliders.children[1].value = 1.0  # alpha = 1: energy only
assert live.result is not before and live.history[-1]["alpha"] == 1.0
assert live.result.report.J_e <= before.report.J_e + 1e-3 and live.result.J != before.J
"""),
    "04_prototype": Expected(images=16, html=1, checks="""
assert robot.name == "prototype" and result.feasible and result.J < 1.0
assert max(summary["tracking_max"].values()) < 0.01
assert summary["peak_rotor_speed_rad_s"] <= summary["planning_speed_limit_rad_s"]
assert set(margins) == set(result.report.constraints) and not broken(margins)
# the take-off from rest shows the jump of J_phi of Fig. 3.50, the start on the plan does not
assert ratio_rest > 2 * max(ratio_on, 1.0) and claims[-1].agree
assert (OUT / "takeoff" / "sim_energy.png").is_file()
"""),
    "05_singularity_crossing": Expected(images=10, html=2, checks="""
assert result.feasible and ours.crossings == 1 and abs(ours.criterion_residual(robot)) < 1e-9
assert not seed[1].feasible and not seed[2].feasible
assert q2[0] > 0 > q2[-1] and np.count_nonzero(np.diff(np.sign(q2))) == 1 and summary["saturated_ticks"] == 0
assert set(margins) == set(result.report.constraints) and not broken(margins)  # no physical limit broken
assert not claims[2].agree and claims[2].why and all(c.agree for c in claims[:2])
from PIL import Image as _PIL
with _PIL.open(gif) as frames:
    assert frames.n_frames > 5  # an animation, not a still
"""),
    "06_replanning": Expected(images=1, html=0, checks="""
assert result.feasible and miss > 0.2 and hit < 0.02  # without replanning it misses, with it within 2 cm
assert [r.used for r in replanner.replans] == [True] and executed_report.feasible
assert log_with.failure is None and log_with.speed.max() <= log_with.speed_limit
assert splice_step <= 1.5 * normal_step  # no rotor-speed jump at the splice
assert slow_record.used and slow_record.delayed_s > 0 and "past the 50 ms deadline" in slow_record.why
assert not late_record.used and "late" in late_record.why and "again" in again.trigger
"""),
    "07_robustness": Expected(images=8, html=0, checks="""
assert len(results) == 4 and all(len(rows) == RUNS == 4 for *_, rows in results.values())  # quick mode
assert all(plan_result.feasible for _, _, plan_result, _ in results.values())
for name in ("square", "prototype-tour"):  # no wind: the plan flies, tracked within 1 cm
    calm = results[name, "wind_y"][3][0]
    assert calm["wind_y"] == 0 and calm["success"]
    assert max(v for k, v in calm.items() if k.startswith("max_error_")) < 0.01
for key, first in breaks.items():  # each margin breaks at a value of its sweep, or not at all
    values = [r[key[1]] for r in results[key][3]]
    assert all(v is None or v in values for v in first.values())
assert len(written) == 8 and all(p.is_file() and p.stat().st_size > 0 for p in written)
"""),
    "08_spatial_fpr": Expected(images=4, html=0, checks="""
assert robot.name == "fpr3" and result.feasible and reference.feasible and result.J < 1.0
assert abs(hover.thrust_vector[0, :, 2].sum() - robot.total_mass * 9.81) < 1e-9
assert np.allclose(hover.attitude[0][:, 1], 0.0)
assert len(paths) == 8 and all(p.is_file() for p in paths)
"""),
}


def _ids(paths):
    return [p.stem for p in paths]


def test_the_numbered_notebooks_are_there():
    names = [p.name for p in NOTEBOOKS]
    assert all(re.fullmatch(r"\d\d_[a-z0-9_]+\.ipynb", n) for n in names), names
    assert {f"{stem}.ipynb" for stem in EXPECTED} <= set(names)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_is_committed_without_outputs(path):
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    assert nb.metadata["kernelspec"]["name"] == "python3"
    assert nb.cells[0].cell_type == "markdown" and nb.cells[0].source.startswith("# ")
    for k, cell in enumerate(nb.cells):
        where = f"{path.name}, cell {k}"
        assert set(cell.metadata) <= {"tags"}, f"{where}: metadata {dict(cell.metadata)} (strip it)"
        if cell.cell_type == "code":
            assert cell.outputs == [], f"{where} has outputs: clear them before committing"
            assert cell.execution_count is None, f"{where}: execution_count {cell.execution_count}, not null"
    first_code = next(c for c in nb.cells if c.cell_type == "code")
    assert "FPR_NOTEBOOK_QUICK" in first_code.source, "read FPR_NOTEBOOK_QUICK in the first code cell"


def _execute(nb, folder: Path, attempts: int = ATTEMPTS):
    """Run every cell of ``nb`` in a fresh python3 kernel in ``folder``; the executed copy.

    A cell that fails raises CellExecutionError (with the cell and the traceback) at once. A cell that times out
    (:data:`CELL_TIMEOUT`: a lost message leaves the kernel idle) or a kernel that dies gets the notebook run
    again from the start in a new kernel, ``attempts`` runs in all; the last error is raised.
    """
    for attempt in range(1, attempts + 1):
        run = copy.deepcopy(nb)
        client = NotebookClient(run, timeout=CELL_TIMEOUT, startup_timeout=STARTUP_TIMEOUT, kernel_name="python3",
                                interrupt_on_timeout=False, resources={"metadata": {"path": str(folder)}})
        try:
            client.execute()
            return run
        except (CellTimeoutError, DeadKernelError) as error:
            if attempt == attempts:
                raise
            warnings.warn(f"run {attempt} of the notebook stopped ({type(error).__name__}: "
                          f"{str(error).splitlines()[0] if str(error) else ''}); running it again in a new kernel",
                          stacklevel=2)
    raise AssertionError("unreachable")


def _outputs(nb, kind: str) -> list[dict]:
    return [o for c in nb.cells if c.cell_type == "code" for o in c.outputs
            if o.output_type in ("display_data", "execute_result") and kind in o.get("data", {})]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=_ids(NOTEBOOKS))
def test_notebook_runs(path, tmp_path, monkeypatch):
    monkeypatch.setenv("FPR_NOTEBOOK_QUICK", "1")
    python_path = [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(python_path))  # the repository, even without pip -e
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    n_cells = len(nb.cells)
    expected = EXPECTED.get(path.stem)
    extra = ["import os, sys\nprint(sys.executable)\nprint(sys.prefix)\nprint(os.getcwd())"]
    if expected is not None:
        extra.append(expected.checks.strip())
    nb.cells += [nbformat.v4.new_code_cell(source) for source in extra]
    nb = _execute(nb, tmp_path)

    # the kernel may send a cell's stdout in several stream messages (seen under load): join them
    printed = "".join(o["text"] for o in nb.cells[n_cells].outputs
                      if o.output_type == "stream" and o.name == "stdout")
    executable, prefix, cwd = printed.split("\n")[:3]
    # the same interpreter in the same environment (a venv's python is a symlink: compare unresolved paths)
    assert (executable, prefix) == (sys.executable, sys.prefix), "the kernel runs another interpreter"
    assert Path(cwd).resolve() == tmp_path.resolve()
    if expected is not None:
        assert len(_outputs(nb, "image/png")) >= expected.images
        assert len(_outputs(nb, "text/html")) >= expected.html


def test_a_notebook_whose_cell_hangs_is_run_again_in_a_new_kernel(tmp_path, monkeypatch):
    """A cell that never answers (here: it sleeps the first time only) times out; the notebook is run again in a
    fresh kernel and passes; a cell that hangs every time fails after the second run.
    """
    monkeypatch.setattr(sys.modules[__name__], "CELL_TIMEOUT", 3)
    marker = tmp_path / "first-run"
    once = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(
        f"import pathlib, time\nm = pathlib.Path({str(marker)!r})\n"
        "if not m.exists():\n    m.touch()\n    time.sleep(60)\nprint('done')")])
    with pytest.warns(UserWarning, match="running it again in a new kernel"):
        run = _execute(once, tmp_path)
    assert run.cells[0].outputs[0]["text"].strip() == "done"
    always = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("import time\ntime.sleep(60)")])
    with pytest.raises(CellTimeoutError), pytest.warns(UserWarning):
        _execute(always, tmp_path)
