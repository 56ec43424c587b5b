"""tools/check_layers.py: the repository passes, and each rule catches what it is for on a small tree made here."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TOOL = ROOT / "tools" / "check_layers.py"


def _run(root: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(TOOL), str(root)], capture_output=True, text=True, timeout=120)


def _tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in {"fpr/__init__.py": "", "fpr/robots/__init__.py": "", "fpr/robots/base.py": "",
                       "fpr/robots/prototype.py": "", "planners/__init__.py": "", **files}.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_the_repository_passes():
    out = _run(ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "no import cycle" in out.stdout


def test_a_clean_small_tree_passes(tmp_path):
    out = _run(_tree(tmp_path, {"fpr/a.py": "import fpr.b\n", "fpr/b.py": "x = 1\n"}))
    assert out.returncode == 0, out.stdout


def test_a_cycle_through_a_function_level_import_is_found(tmp_path):
    out = _run(_tree(tmp_path, {"fpr/a.py": "import fpr.b\n",
                                "fpr/b.py": "def f():\n    from fpr import a\n    return a\n"}))
    assert out.returncode == 1
    assert "import cycle: fpr.a <-> fpr.b" in out.stdout


def test_a_relative_import_cycle_is_found(tmp_path):
    out = _run(_tree(tmp_path, {"planners/x.py": "from .y import f\n", "planners/y.py": "from . import x\nf = 1\n"}))
    assert "import cycle: planners.x <-> planners.y" in out.stdout


@pytest.mark.parametrize("line", ['if robot.name == "prototype":', "if name in ('prototype', 'other'):",
                                  'ok = "prototype" != kind'])
def test_a_branch_on_a_robots_name_outside_fpr_robots_is_found(tmp_path, line):
    out = _run(_tree(tmp_path, {"planners/m.py": f"{line}\n    pass\n" if line.endswith(":") else line + "\n"}))
    assert out.returncode == 1
    assert "branch on a robot's name outside fpr/robots/: planners/m.py:1" in out.stdout


def test_a_robot_may_name_itself_in_its_own_module(tmp_path):
    out = _run(_tree(tmp_path, {"fpr/robots/prototype.py": 'NAME = "prototype"\nif NAME == "prototype":\n    pass\n'}))
    assert out.returncode == 0, out.stdout


def test_a_long_file_is_found(tmp_path):
    out = _run(_tree(tmp_path, {"controllers/__init__.py": "", "controllers/big.py": "x = 1\n" * 701}))
    assert out.returncode == 1
    assert "controllers/big.py has 701 lines (at most 700)" in out.stdout


def test_planners_top_level_is_at_most_ten_entries(tmp_path):
    files = {f"planners/m{i}.py": "" for i in range(6)}
    files.update({f"planners/p{i}/__init__.py": "" for i in range(4)})
    assert _run(_tree(tmp_path, files)).returncode == 0
    files["planners/extra.py"] = ""
    out = _run(_tree(tmp_path, files))
    assert out.returncode == 1
    assert "planners/ has 11 modules and packages at its top level (at most 10)" in out.stdout
