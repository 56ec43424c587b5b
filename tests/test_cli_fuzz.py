"""Fuzzing ``python -m fpr.plan`` (Hypothesis): mission files and option sets, valid and not.

Every outcome must be exit 0, 1 or 2 (never 3, a bug), with at most one line per error on stderr and no
traceback, within a time bound. Sizes are kept small so that each case runs fast: ``--method none``,
``--no-plots``, a low ``--rate``, missions of a few seconds (longer ones are refused by the size checks).
Derandomized: the same cases on every run, so that CI is deterministic.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from fpr.cli.plan import main  # noqa: E402
from planners.missions.mission import BUILTIN_MISSIONS  # noqa: E402

TIME_BOUND = 60.0  # [s] per case; a valid case takes about 0.5 s here

ODD_FLOATS = st.sampled_from([0.0, -1.0, 1e9, -1e-9, math.nan, math.inf, -math.inf, 1e308, 5e-324])
SMALL_TIMES = st.floats(min_value=0.2, max_value=6.0)
TIMES = st.one_of(*[SMALL_TIMES] * 6, ODD_FLOATS)
SPACE_FPR = [0.0, 0.0, 3.9269908169872414, 1.5707963267948966]


def _toml(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value == math.inf else "-inf" if value == -math.inf
                                                 else repr(value))
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return str(value)


@st.composite
def way_points(draw, robot):
    k = draw(st.sampled_from([1, 2, 2, 2, 3, 3, 4]))
    n = 2 if robot == "prototype" else 4
    if draw(st.integers(0, 7)) == 0:
        n = draw(st.integers(min_value=0, max_value=5))
    base = [1.0, -0.3] if robot == "prototype" else SPACE_FPR
    points = []
    for _ in range(k):
        point = [base[j % len(base)] + draw(st.floats(min_value=-0.3, max_value=0.3)) for j in range(n)]
        if draw(st.integers(0, 19)) == 0 and point:
            point[draw(st.integers(0, len(point) - 1))] = draw(ODD_FLOATS)
        points.append(point)
    return points


@st.composite
def mission_text(draw) -> str:
    """The text of a mission file: mostly well formed with odd values, sometimes not TOML at all."""
    if draw(st.integers(0, 14)) == 0:
        return draw(st.text(max_size=60))
    robot = draw(st.sampled_from(["fpr", "fpr", "prototype", "prototype", "tripod", 3]))
    fields = {"robot": robot, "way_points": draw(way_points(robot))}
    travels = max(len(fields["way_points"]) - 1, 0) + draw(st.sampled_from([0] * 8 + [1, -1]))
    fields["times"] = [draw(TIMES) for _ in range(max(travels, 0))]
    if draw(st.booleans()):
        fields["via_points"] = draw(st.one_of(st.integers(-2, 3), st.sampled_from([1000, 10**9]),
                                              st.floats(allow_nan=True)))
    if draw(st.booleans()):
        fields["alpha"] = draw(st.one_of(st.floats(0, 1), ODD_FLOATS))
    if draw(st.integers(0, 4)) == 0:
        fields["space"] = draw(st.sampled_from(["task", "joint", "polar"]))
    if draw(st.integers(0, 4)) == 0:
        fields["arm"] = draw(st.sampled_from(["down", "up", "sideways"]))
    if draw(st.integers(0, 6)) == 0:
        fields["cross_singularity"] = draw(st.booleans())
    if draw(st.integers(0, 6)) == 0:
        fields[draw(st.sampled_from(["speed", "name", "description"]))] = draw(st.one_of(st.text(max_size=8),
                                                                                         st.integers()))
    lines = [f"{key} = {_toml(value)}" for key, value in fields.items()]
    if draw(st.integers(0, 3)) == 0:
        key = draw(st.sampled_from(["link_length", "drone_mass", "link_mass", "hinge_offset", "drone_izz", "mass"]))
        lines += ["[robot_parameters]", f"{key} = {_toml(draw(st.one_of(st.floats(0.01, 2.0), ODD_FLOATS)))}"]
    return "\n".join(lines) + "\n"


NUMBER_TEXT = st.one_of(st.sampled_from(["0", "-1", "1e9", "nan", "inf", "abc", "", "1,2", "3,,3"]),
                        st.floats(min_value=0.1, max_value=5).map(repr))


@st.composite
def options(draw) -> list[str]:
    """A set of options around ``--method none --no-plots --quiet`` (the fast path), valid and not."""
    argv = []
    if draw(st.integers(0, 3)) == 0:
        argv += ["--rate", draw(st.sampled_from(["0", "-3", "nan", "1e9", "x"]))]
    else:
        argv += ["--rate", draw(st.floats(1, 20).map(repr))]
    if draw(st.integers(0, 3)) == 0:
        argv += ["--times", draw(NUMBER_TEXT)]
    if draw(st.integers(0, 4)) == 0:
        argv += ["--alpha", draw(st.sampled_from(["0.3", "2", "nan", "-0", "x"]))]
    if draw(st.integers(0, 4)) == 0:
        argv += ["--via-points", draw(st.sampled_from(["0", "2", "-1", "1000", "1.5", "1,2"]))]
    if draw(st.integers(0, 3)) == 0:
        key = draw(st.sampled_from(["link_length", "drone_mass", "link_mass", "drone_ixx", "gravity", ""]))
        value = draw(st.one_of(st.sampled_from(["0", "-1", "1e6", "nan", "x"]), st.floats(0.05, 2).map(repr)))
        argv += ["--set", f"{key}={value}"]
    if draw(st.integers(0, 5)) == 0:
        argv += ["--robot", draw(st.sampled_from(["fpr", "prototype", "tripod"]))]
    if draw(st.integers(0, 4)) == 0:  # simulation options, mostly refused before the (slower) simulation
        argv += ["--simulate", "--hold", draw(st.sampled_from(["0", "-1", "nan", "1e6"]))]
        option = draw(st.sampled_from(["--wind", "--noise", "--initial-error", "--model-mass-scale",
                                       "--rotor-constant-scale"]))
        value = {"--wind": ["1,2", "0,0,nan", "a,b,c", "0,0,0,0"], "--noise": ["-0.01,-0.01", "1", "0,inf"],
                 "--initial-error": ["bogus=1", "y=nan", "y"], "--model-mass-scale": ["0", "-1", "inf"],
                 "--rotor-constant-scale": ["0", "nan", "1e9"]}[option]
        argv += [option, draw(st.sampled_from(value))]
    return argv


def _check_outcome(code: int, err: str, elapsed: float) -> None:
    assert code in (0, 1, 2), (code, err)
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert all(line.startswith(("error:", "warning:")) for line in lines), err
    if code == 2:
        assert len(lines) == 1, err
    if code == 1:
        assert 1 <= len(lines) <= 2, err  # a violated constraint and/or a lost robot, one line each
    assert elapsed < TIME_BOUND, elapsed


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(text=mission_text(), argv=options())
def test_mission_files_and_options(capsys, text, argv):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "mission.toml"
        path.write_text(text, encoding="utf-8")
        start = time.perf_counter()
        code = main(["--mission", str(path), "--method", "none", "--no-plots", "--quiet", *argv,
                     "--out", str(Path(folder) / "out")])
        err = capsys.readouterr().err
        _check_outcome(code, err, time.perf_counter() - start)
        out = Path(folder) / "out"
        assert out.exists() == (code in (0, 1)), (code, err)  # a failed run writes nothing
        leftovers = [p.name for p in Path(folder).iterdir() if p.name not in ("mission.toml", "out")]
        assert not leftovers


@settings(max_examples=15, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(mission=st.sampled_from(BUILTIN_MISSIONS), argv=options())
def test_builtin_missions_and_options(capsys, mission, argv):
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        code = main(["--mission", mission, "--method", "none", "--no-plots", "--quiet", *argv,
                     "--out", str(Path(folder) / "out")])
        _check_outcome(code, capsys.readouterr().err, time.perf_counter() - start)
