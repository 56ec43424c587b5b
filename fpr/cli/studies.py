"""The thesis' planning studies from the command line: ``python -m fpr.studies [--out DIR] [--quick]``.

The studies themselves (:func:`~fpr.studies.thesis.via_point_study`, :func:`~fpr.studies.thesis.alpha_study`,
:func:`~fpr.studies.thesis.method_comparison`: seed 3.2.5, 3.2.6 and appendix) are in
:mod:`fpr.studies.thesis`, and importable from here too. This module formats them: it runs the three
studies (``--quick``: fewer cases), prints one table per study (:func:`format_table`), writes
``via_points.png`` (Fig. 3.7-3.8), ``alpha.png`` (Fig. 3.9-3.10), the figures of each optimised square
motion against the stop-at-way-points one (Fig. 3.11-3.18, one folder per method;
:func:`write_study_figures`) and ``studies.json`` (:func:`studies_document`) into ``--out`` (default
``fpr-out/studies``).
"""

from __future__ import annotations

import json
import math
import os
import platform
import sys
import time
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from fpr.cli import contract
from fpr.cli.output import OutputFolder, inputs_hash, manifest, write_manifest
from fpr.cli.plan_files import split_timings
from fpr.studies.thesis import (
    ALPHAS,
    COMPARED_METHODS,
    COMPARISON_MISSION,
    STUDY_MISSION,
    VIA_POINT_COUNTS,
    AlphaStudy,
    Case,
    MethodComparison,
    ViaPointStudy,
    alpha_study,
    method_comparison,
    via_point_study,
)
from fpr.tuning import tune_process
from fpr.views.figures import alpha_study_figure, plan_figures, via_point_study_figure
from fpr.views.figures.studies import APPENDIX_FIGURES
from planners.missions.mission import load_mission

QUICK = {"counts": (0, 1), "alphas": (0.0, 0.5, 1.0), "methods": COMPARED_METHODS}
"""Settings of ``--quick``."""


def format_value(value, digits: int = 4) -> str:
    """Text of one table cell: floats with ``digits`` significant digits, bools as yes / no, None as -."""
    if value is None:
        return "-"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.{digits}g}"
    return str(value)


def format_table(rows: Iterable[Mapping], digits: int = 4) -> str:
    """A plain-text table: one column per key (in order of first appearance), one line per row.

    Numbers are right-aligned, text left-aligned; a missing key gives ``-``. Each cell is
    :func:`format_value` of the value.
    """
    rows = list(rows)
    if not rows:
        return ""
    keys = list(dict.fromkeys(k for r in rows for k in r))
    cells = [[format_value(r.get(k), digits) for k in keys] for r in rows]
    def is_number(v):
        return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)

    numeric = [all(is_number(r[k]) for r in rows if r.get(k) is not None) for k in keys]
    widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]

    def line(values):
        cells_ = (v.rjust(w) if num else v.ljust(w) for v, w, num in zip(values, widths, numeric, strict=True))
        return "  ".join(cells_).rstrip()

    return "\n".join([line(keys), line(["-" * w for w in widths])] + [line(c) for c in cells])


def write_study_figures(out_dir: str | Path, via: ViaPointStudy | None = None,
                        alpha: AlphaStudy | None = None, comparison: MethodComparison | None = None,
                        rate: float = 200.0) -> list[Path]:
    """Write the studies' figures into ``out_dir`` (created if needed).

    * ``via_points.png``: Fig. 3.7-3.8 (:func:`fpr.views.figures.via_point_study_figure`);
    * ``alpha.png``: Fig. 3.9-3.10 (:func:`fpr.views.figures.alpha_study_figure`);
    * ``<mission>-<method>/*.png``: for each optimised method of ``comparison``, the figures of
      :func:`fpr.views.figures.plan_figures` (appendix, Fig. 4.11-4.18) against the stop-at-way-points motion
      (when ``"none"`` is among its methods).

    Returns:
        the paths of the written PNG files.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if via is not None:
        written.append(via_point_study_figure(out / "via_points.png", via.counts, via.energy_ratio,
                                              via.perturbation_ratio))
    if alpha is not None:
        written.append(alpha_study_figure(out / "alpha.png", alpha.alphas, alpha.energy_ratio,
                                          alpha.perturbation_ratio))
    if comparison is not None:
        reference = None
        if "none" in comparison.methods:
            reference = comparison.plan("none").sampled(rate)
        for method, result in zip(comparison.methods, comparison.plans, strict=True):
            if method == "none":
                continue
            folder = out / f"{comparison.mission}-{method}"
            written += plan_figures(folder, result.robot, result.sampled(rate), reference,
                                    figure_numbers=APPENDIX_FIGURES.get(method))
    return written


def studies_document(via: ViaPointStudy | None = None, alpha: AlphaStudy | None = None,
                     comparison: MethodComparison | None = None, **extra) -> dict:
    """The JSON document of ``studies.json``: the machine, then each study's numbers."""
    doc = {"machine": {"python": platform.python_version(), "numpy": np.__version__,
                       "cpu_count": os.cpu_count(), "platform": platform.platform()}, **extra}
    for key, study in (("via_points", via), ("alpha", alpha), ("methods", comparison)):
        if study is not None:
            doc[key] = study.to_dict()
    return doc


def _json_safe(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def _exit_codes() -> str:
    """fpr.plan's exit codes, with 1 unused: an infeasible case is a finding of a study, not a failure."""
    lines, out, skipping = contract.EXIT_CODES.splitlines(), [], False
    for line in lines:
        if line.startswith("  1 "):
            skipping = True
            out.append("  1    not used: an infeasible case is a finding of the study, shown in its table")
        elif skipping and line.startswith("       "):
            continue
        else:
            skipping = False
            out.append(line)
    return "\n".join(out)


def parser() -> contract.Parser:
    """The argument parser of ``python -m fpr.studies``."""
    p = contract.Parser(prog="python -m fpr.studies", description=__doc__.split("\n\n")[0],
                        formatter_class=contract.HelpFormatter,
                        epilog=_exit_codes())
    p.add_argument("--out", type=Path, default=Path("fpr-out") / "studies",
                   help="output folder, replaced atomically when the studies are done")
    p.add_argument("--quick", action="store_true",
                   help=f"fewer cases: n_vp in {QUICK['counts']}, alpha in {QUICK['alphas']}")
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG figures")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    contract.add_debug(p)
    return p


def _run(args, argv) -> int:
    progress = None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True))
    counts = QUICK["counts"] if args.quick else VIA_POINT_COUNTS
    alphas = QUICK["alphas"] if args.quick else ALPHAS
    started, start = time.time(), time.perf_counter()
    folder = OutputFolder(args.out)
    try:
        tmp = folder.open()  # a bad --out is refused before minutes of work
        robot = load_mission(STUDY_MISSION).load_robot()
        via = via_point_study(counts=counts, robot=robot, progress=progress)
        alpha = alpha_study(alphas=alphas, robot=robot, progress=progress)
        comparison = method_comparison(robot=robot, progress=progress)
        for title, study in ((f"Via points (mission {via.mission!r}, {via.method}, alpha = {via.alpha:g}); "
                              "ratios divide by the n_vp = 0 case (seed Fig. 3.7-3.8)", via),
                             (f"Weight alpha (mission {alpha.mission!r}, {alpha.method}, "
                              f"n_vp = {alpha.via_points}); J_e / J_e|alpha=0, J_phi / J_phi|alpha=1 "
                              "(seed Fig. 3.9-3.10)", alpha),
                             (f"Methods (mission {comparison.mission!r}); J_e0, J_phi0: stop at way points "
                              "(seed appendix, Fig. 3.11-3.18)", comparison)):
            print(title)
            print(format_table(study.rows()))
            print()
        written = [] if args.no_plots else write_study_figures(tmp, via, alpha, comparison)
        doc = _json_safe(studies_document(via, alpha, comparison, quick=bool(args.quick)))
        times = split_timings(doc)  # to the manifest: studies.json is the same bytes from run to run
        (tmp / "studies.json").write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        files = sorted(str(p.relative_to(tmp)) for p in tmp.rglob("*") if p.is_file())
        options = {"quick": bool(args.quick), "no_plots": bool(args.no_plots)}
        timings = {"planning_s": times, "total_s": round(time.perf_counter() - start, 3)}
        write_manifest(tmp, manifest(parser().prog.split() + list(argv), inputs_hash("", options), started,
                                     time.perf_counter() - start, contract.OK,
                                     f"{len(via.cases) + len(alpha.cases) + len(comparison.cases)} cases planned",
                                     files, timings))
        folder.commit()
    except BaseException:
        folder.discard()
        raise
    print(f"wrote studies.json, {len(written)} figures and manifest.json into {folder.path} "
          f"({time.perf_counter() - start:.1f} s)")
    return contract.OK


def main(argv=None) -> int:
    """Run the three studies, print their tables, write the figures, ``studies.json`` and ``manifest.json``.

    Returns:
        The exit code: 0, or 2 (bad input, e.g. an --out that cannot be written), 3 (a bug), 130 (Ctrl-C);
        see ``--help``. The planning times are in ``manifest.json``, so ``studies.json`` is the same bytes
        from one run to the next.
    """
    tune_process()  # one BLAS thread, freed memory kept in glibc's heap (fpr.tuning)
    return contract.command(parser(), argv, _run)


__all__ = [
    "ALPHAS",
    "COMPARISON_MISSION",
    "AlphaStudy",
    "COMPARED_METHODS",
    "Case",
    "MethodComparison",
    "QUICK",
    "STUDY_MISSION",
    "VIA_POINT_COUNTS",
    "ViaPointStudy",
    "alpha_study",
    "format_table",
    "format_value",
    "main",
    "method_comparison",
    "studies_document",
    "via_point_study",
    "write_study_figures",
]

if __name__ == "__main__":
    raise SystemExit(main())
