#!/usr/bin/env python3
"""Check the layering of fpr's packages (``fpr``, ``planners``, ``controllers``); run from the repository's root.

Four checks, each a rule of the project (STYLE.md):

* **No import cycle** between modules, function-level imports included (importing inside a function does not
  make a cycle go away, it hides it). A module importing its own package's ``__init__`` is not an edge.
* **No branch on a robot's name** outside ``fpr/robots/``: a comparison such as ``robot.name == "prototype"``
  or ``name in ("fpr", ...)``; what differs between robots belongs to the robot's module (a registry of
  robot kinds, :mod:`fpr.robots`). The names are the modules of ``fpr/robots/`` (but ``base``).
* **No file over** :data:`MAX_LINES` **lines**: a longer one holds more than one concept.
* **planners/ has at most** :data:`MAX_PLANNERS_TOP` **modules and packages at its top level**: the folder is
  organised by concept (trajectory, missions, problem, optimisation, ...); a new concept goes into one of them
  or becomes a package, not a loose file.

Usage: ``python tools/check_layers.py [ROOT]``. Prints one line per problem and exits 1, or one summary
line and exits 0.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

#: The packages checked.
PACKAGES = ("fpr", "planners", "controllers")
#: Longest file [lines].
MAX_LINES = 700
#: Most modules and packages directly in planners/ (``__init__.py`` not counted).
MAX_PLANNERS_TOP = 10
#: Where a robot may name itself.
ROBOTS_FOLDER = "fpr/robots/"


def modules(root: Path) -> dict[str, Path]:
    """Every module of :data:`PACKAGES` by dotted name (a package by its own name, not ``.__init__``)."""
    found = {}
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            name = ".".join(path.relative_to(root).with_suffix("").parts)
            found[name.removesuffix(".__init__")] = path
    return found


def imported(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The modules of ``known`` that module ``name`` imports anywhere in its file (functions included)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    edges = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the package, up level - 1
                parts = package.split(".")
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            targets = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            own_package = name.startswith(target + ".") and known.get(target, path).name == "__init__.py"
            if target and target != name and not own_package:
                edges.add(target)
    return edges


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative), sorted."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return sorted(found)


def robot_names(root: Path) -> tuple[str, ...]:
    """The built-in robots' names: the modules of fpr/robots/ but ``base`` and the private ones, and the prefixes
    of their variants (``prototype_thrust`` is the prototype's).
    """
    names = set()
    for path in (root / ROBOTS_FOLDER).glob("*.py"):
        if path.stem not in ("__init__", "base") and not path.stem.startswith("_"):
            names.add(path.stem.split("_")[0])
    return tuple(sorted(names))


def name_branches(root: Path, files: dict[str, Path]) -> list[str]:
    """``path:line`` of each comparison with a robot's name outside :data:`ROBOTS_FOLDER`."""
    names = "|".join(re.escape(n) for n in robot_names(root))
    if not names:
        return []
    quoted = rf"""["']({names})["']"""
    pattern = re.compile(rf"(==|!=)\s*{quoted}|{quoted}\s*(==|!=)|\bin\s*[(\[{{]\s*{quoted}")
    found = []
    for path in files.values():
        relative = path.relative_to(root).as_posix()
        if relative.startswith(ROBOTS_FOLDER):
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if pattern.search(line) and not line.lstrip().startswith("#"):
                found.append(f"{relative}:{number}")
    return found


def long_files(root: Path, files: dict[str, Path]) -> list[tuple[str, int]]:
    """(path, lines) of the files over :data:`MAX_LINES` lines, longest first."""
    sizes = [(path.relative_to(root).as_posix(), len(path.read_text(encoding="utf-8").splitlines()))
             for path in files.values()]
    return sorted(((p, n) for p, n in sizes if n > MAX_LINES), key=lambda item: -item[1])


def planners_top(root: Path) -> list[str]:
    """The modules and packages directly in planners/ (not ``__init__.py``, not ``__pycache__``)."""
    folder = root / "planners"
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir()
                  if (p.suffix == ".py" and p.name != "__init__.py") or (p.is_dir() and (p / "__init__.py").exists()))


def check(root: Path) -> tuple[list[str], str]:
    """The problems found under ``root`` (one line each) and the summary line."""
    files = modules(root)
    graph = {name: imported(name, path, files) for name, path in files.items()}
    problems = [f"import cycle: {' <-> '.join(component)}" for component in cycles(graph)]
    problems += [f"branch on a robot's name outside {ROBOTS_FOLDER}: {where}" for where in name_branches(root, files)]
    problems += [f"{path} has {lines} lines (at most {MAX_LINES})" for path, lines in long_files(root, files)]
    top = planners_top(root)
    if len(top) > MAX_PLANNERS_TOP:
        problems.append(f"planners/ has {len(top)} modules and packages at its top level (at most "
                        f"{MAX_PLANNERS_TOP}): {', '.join(top)}")
    longest = max((len(p.read_text(encoding="utf-8").splitlines()) for p in files.values()), default=0)
    summary = (f"layers: {len(files)} modules, no import cycle, no branch on a robot's name outside "
               f"{ROBOTS_FOLDER}, longest file {longest} lines, planners/ top level {len(top)} entries")
    return problems, summary


def main(argv: list[str] | None = None) -> int:
    """Run :func:`check` on the root given (default: the current folder); 0 when clean, 1 otherwise."""
    args = sys.argv[1:] if argv is None else argv
    root = Path(args[0] if args else ".").resolve()
    problems, summary = check(root)
    for problem in problems:
        print(problem)
    if problems:
        print(f"layers: {len(problems)} problem(s)")
        return 1
    print(summary)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
