"""The README and the documentation site: what they promise holds.

The README stays short and keeps the two commands that CI runs; its links resolve; its first example runs; no
user document, docstring or comment carries a work-item number; the benchmark page's renderer reads the committed
run and says "not measured" for a part the run lacks instead of failing the build.
"""

from __future__ import annotations

import copy
import json
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAIN_COMMAND = "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && python -m fpr.plan"
TEST_COMMAND = 'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" && python -m pytest'


def test_readme_is_short_and_keeps_both_commands():
    text = README.read_text()
    assert len(text.splitlines()) <= 200
    assert MAIN_COMMAND in text and TEST_COMMAND in text
    # CI runs the test command verbatim after making its own virtual environment
    assert TEST_COMMAND.split("activate && ", 1)[1] in (ROOT / ".ci" / "run").read_text()


def test_readme_links_resolve():
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README.read_text())
    assert links, "the README links to the documentation"
    missing = [link for link in links if "://" not in link and not (ROOT / link).exists()]
    assert not missing, missing


def test_every_guide_is_in_the_table_of_contents():
    index = (ROOT / "docs" / "index.md").read_text()
    guides = sorted(p.stem for p in (ROOT / "docs" / "guides").glob("*.md"))
    assert guides
    assert [g for g in guides if f"guides/{g}\n" not in index] == []


def test_repository_paths_named_in_the_documents_exist():
    pattern = re.compile(r"`((?:tests|fpr|planners|controllers|urdf|notebooks|docs)/[A-Za-z0-9_./-]+)`")
    documents = [README, ROOT / "CHANGELOG.md", *(ROOT / "docs").rglob("*.md")]
    named = {m for p in documents for m in pattern.findall(p.read_text())}
    assert len(named) > 50
    assert sorted(n for n in named if not (ROOT / n).exists() and not n.startswith("docs/_build")) == []


def test_readme_first_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # it writes scene.html
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert len(blocks) >= 2
    for block in blocks:
        exec(compile(block, "README.md", "exec"), {"__name__": "readme"})  # noqa: S102
    assert (tmp_path / "scene.html").stat().st_size > 0


WORK_ITEM = re.compile(r"\b[Ii]ssues? [0-9]+|\(i[0-9]+\)|\bround s?[0-9]+\b")


def test_no_work_item_numbers_in_documents_and_code():
    files = [README, ROOT / "CHANGELOG.md", *(ROOT / "docs").rglob("*.md"), *(ROOT / "notebooks").glob("*.ipynb")]
    for package in ("fpr", "planners", "controllers"):
        files += [p for p in (ROOT / package).rglob("*") if p.suffix in (".py", ".c", ".h", ".toml")]
    hits = [f"{p.relative_to(ROOT)}: {m.group(0)}" for p in files for m in WORK_ITEM.finditer(p.read_text())]
    assert not hits, hits


# ---------------------------------------------------------------------------------------- the benchmark page
@pytest.fixture(scope="module")
def bench_tables():
    """docs/_ext/bench_render.py: the renderer behind the benchmark page (pure Python)."""
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        import bench_render
    finally:
        sys.path.pop(0)
    return bench_render


@pytest.fixture(scope="module")
def committed_run():
    return json.loads((ROOT / "docs" / "bench" / "bench.json").read_text())


def _text(items) -> str:
    return " ".join(item if isinstance(item, str) else " ".join([*item.header, *sum(item.rows, [])]) for item in items)


def test_committed_run_renders_every_part(bench_tables, committed_run):
    # the native parts' rows come with the benchmark's native section; a run made before it has none
    absent = set() if "native_parts" in committed_run.get("control", {}) else {"native"}
    for part in set(bench_tables.PARTS) - absent:
        rendered = bench_tables.render(committed_run, part)
        assert rendered and all(isinstance(t, bench_tables.Table) and t.rows for t in rendered), part
        assert "Not measured" not in _text(rendered), part
    # numbers come from the file: the scaling table shows each robot's and length's median time, the families
    # table each family's p95, as the JSON has them
    scaling = _text(bench_tables.render(committed_run, "scaling"))
    assert all(bench_tables.fmt_time(row["median_s"]) in scaling for row in committed_run["scaling"]["robots"])
    families = _text(bench_tables.render(committed_run, "families"))
    assert all(bench_tables.fmt_time(row["p95_s"]) in families
               for row in committed_run["planning"]["families"]["rows"])


def test_missing_or_reshaped_parts_say_not_measured(bench_tables, committed_run):
    partial = {k: v for k, v in committed_run.items() if k not in ("scaling", "replan")}
    assert "Not measured" in _text(bench_tables.render(partial, "scaling"))
    assert "Not measured" in _text(bench_tables.render(partial, "replan-phases"))
    assert "Not measured" in _text(bench_tables.render(None, "goals"))
    reshaped = copy.deepcopy(committed_run)
    reshaped["control"]["simulation"] = [1, 2, 3]  # a schema change under the renderer
    assert "Not measured" in _text(bench_tables.render(reshaped, "simulation"))
    older = copy.deepcopy(committed_run)
    del older["planning"]["families"]  # a run made before the planning section had its families
    assert "Not measured" in _text(bench_tables.render(older, "families"))
    # the parts still present render as before
    assert "Not measured" not in _text(bench_tables.render(partial, "planning"))


def test_native_parts_render_when_the_run_has_them(bench_tables, committed_run):
    run = copy.deepcopy(committed_run)
    run["control"].update(
        yardstick=dict(crba_s=4e-6, constraint_dynamics_s=2e-5, normalised_to_crba_s=2e-6),
        pinocchio_per_tick=dict(ticks=6501, calls={"crba": dict(per_tick=1.0, raw_s=4e-6)}, per_tick_s=4e-6),
        native_parts=dict(runs=3, simulated_s=13.0, ticks=6501, rows=[
            dict(label="every part native", wall_s=0.5, real_time_factor=26.0, tick_s=8e-5, slowdown=1.0),
            dict(label="no part native (Python paths)", wall_s=1.3, real_time_factor=10.0, tick_s=2e-4, slowdown=2.6)]))
    on_off = bench_tables.render(run, "native")[-1]
    assert [r[0] for r in on_off.rows] == ["every part native", "no part native (Python paths)"]
    assert on_off.rows[0][3] == "52" and on_off.rows[0][5] == "20"  # RTF x crba / 2 us; tick / its Pinocchio calls


def test_time_format(bench_tables):
    assert bench_tables.fmt_time(2.5e-6) == "2.5 µs"
    assert bench_tables.fmt_time(0.0123) == "12.3 ms"
    assert bench_tables.fmt_time(1.5) == "1.5 s"
    assert bench_tables.fmt_time(None) == "—"
