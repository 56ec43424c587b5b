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


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
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


@settings(max_examples=15, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(mission=st.sampled_from(BUILTIN_MISSIONS), argv=options())
def test_builtin_missions_and_options(capsys, mission, argv):
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        code = main(["--mission", mission, "--method", "none", "--no-plots", "--quiet", *argv,
                     "--out", str(Path(folder) / "out")])
        _check_outcome(code, capsys.readouterr().err, time.perf_counter() - start)


# ---------------------------------------------------------------------- the mission reader, any TOML at all
KEYS = st.sampled_from(["robot", "way_points", "times", "via_points", "alpha", "space", "arm", "name", "description",
                        "cross_singularity", "robot_parameters", "events", "speed", "a.b", '"q uo"', "x" * 300])
SCALARS = st.one_of(
    st.integers(min_value=-(2 ** 63), max_value=2 ** 63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e-300, 1e300, 5e-324, -0.0, 0.0]),
    st.booleans(),
    st.text(max_size=20),
    st.sampled_from(["1979-05-27", "07:32:00", "1979-05-27T07:32:00Z"]),  # TOML dates and times (bare)
)


def _toml_scalar(value) -> str:
    if isinstance(value, str) and value[:2] in ("19", "07"):
        return value
    return _toml(value)


TOML_VALUES = st.recursive(SCALARS.map(_toml_scalar),
                           lambda inner: st.one_of(
                               st.lists(inner, max_size=5).map(lambda xs: "[" + ", ".join(xs) + "]"),
                               st.dictionaries(st.sampled_from(["at", "kind", "force", "duration", "body",
                                                                "link_length", "drone_mass", "to", "way_point"]),
                                               inner, max_size=4)
                               .map(lambda d: "{" + ", ".join(f"{k} = {v}" for k, v in d.items()) + "}")),
                           max_leaves=12)
ENCODINGS = st.sampled_from(["utf-8", "utf-8", "utf-8", "utf-8-sig", "utf-16", "latin-1"])


@st.composite
def toml_document(draw) -> bytes:
    """A TOML-ish document: random keys (mission ones and others) with nested values, sometimes a valid
    mission with one field replaced, sometimes raw bytes; in some encoding.
    """
    choice = draw(st.integers(0, 9))
    if choice == 0:
        return draw(st.binary(max_size=200))
    lines = []
    if choice <= 4:  # a mission with one field made odd
        base = {"robot": '"fpr"', "way_points": "[" + ", ".join([_toml(SPACE_FPR)] * 2) + "]", "times": "[3.0]"}
        base[draw(st.sampled_from(sorted(base)))] = draw(TOML_VALUES)
        lines += [f"{k} = {v}" for k, v in base.items()]
    for _ in range(draw(st.integers(0, 4))):
        lines.append(f"{draw(KEYS)} = {draw(TOML_VALUES)}")
    if draw(st.integers(0, 4)) == 0:
        lines.append(draw(st.sampled_from(["[robot_parameters]", "[[events]]", "[a.b.c]", "[[way_points]]"])))
        lines.append(f"{draw(KEYS)} = {draw(TOML_VALUES)}")
    text = "\n".join(lines) + "\n"
    return text.encode(draw(ENCODINGS), errors="replace")


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(document=toml_document())
def test_the_mission_reader_on_any_toml(capsys, document):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "mission.toml"
        path.write_bytes(document)
        start = time.perf_counter()
        code = main(["--mission", str(path), "--method", "none", "--no-plots", "--quiet", "--rate", "20",
                     "--out", str(Path(folder) / "out")])
        _check_outcome(code, capsys.readouterr().err, time.perf_counter() - start)


# ----------------------------------------------------------------------------- every numeric option, extremes
EXTREMES = st.sampled_from([1e-300, -1e-300, 1e300, -1e300, 5e-324, -5e-324, -0.0, 0.0, math.nan, math.inf,
                            -math.inf, 1e-9, 0.5, 1.0, 3.0])
NUMERIC_OPTIONS = ["--rate", "--alpha", "--times", "--set drone_mass", "--set link_length", "--set hinge_offset",
                   "--set end_effector_mass", "--model-mass-scale", "--rotor-constant-scale", "--wind", "--noise",
                   "--hold", "--initial-error", "--replan-deadline", "--replan-bound", "--replan-rate"]
SIMULATION = {"--model-mass-scale", "--rotor-constant-scale", "--wind", "--noise", "--hold", "--initial-error"}
REPLANNING = {"--replan-deadline", "--replan-bound", "--replan-rate"}


def _argument(option: str, value: float, other: float) -> list[str]:
    if option.startswith("--set "):
        return ["--set", f"{option[6:]}={value!r}"]
    if option == "--wind":
        return [f"--wind={value!r},{other!r},0"]
    if option == "--noise":
        return [f"--noise={value!r},{other!r}"]
    if option == "--initial-error":
        return ["--initial-error", f"y={value!r}"]
    return [f"{option}={value!r}"]


@settings(max_examples=80, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(option=st.sampled_from(NUMERIC_OPTIONS), value=EXTREMES, other=EXTREMES, simulate=st.booleans())
def test_every_numeric_option_at_its_extremes(capsys, option, value, other, simulate):
    argv = _argument(option, value, other)
    if option in SIMULATION | REPLANNING and simulate:
        argv += ["--simulate", "--hold", "0.2"] if option != "--hold" else ["--simulate"]
    if option in REPLANNING and simulate:
        argv += ["--replan"]
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        code = main(["--mission", "study", "--method", "none", "--no-plots", "--quiet", *argv,
                     *(["--rate", "20"] if option != "--rate" else []), "--out", str(Path(folder) / "out")])
        _check_outcome(code, capsys.readouterr().err, time.perf_counter() - start)


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(option=st.sampled_from(["--runs", "--seed", "--workers", "--hold", "--tracking-tolerance", "--min-success",
                               "--model-mass-scale", "--wind", "--vary model_mass_scale", "--vary wind",
                               "--vary drone_mass", "--vary initial_error.y"]),
       value=st.one_of(EXTREMES, st.sampled_from([0, -1, 2 ** 64, 10 ** 30, 1000, 1]).map(float)),
       other=EXTREMES)
def test_every_campaign_option_at_its_extremes(capsys, monkeypatch, option, value, other):
    """The campaign's checks (the runs themselves stubbed: a valid input reaches the cluster, which is then
    interrupted, exit 130).
    """
    from fpr.cli import campaign

    def no_cluster(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(campaign, "_client", no_cluster)
    monkeypatch.setattr(campaign.workers, "end_children", lambda: None)
    if option in ("--runs", "--seed", "--workers"):
        argv = [f"{option}={int(value) if math.isfinite(value) else value!r}"]
    elif option.startswith("--vary "):
        distribution = st.sampled_from  # (the distributions' own grammar is tested in test_campaign.py)
        del distribution
        argv = ["--vary", f"{option[7:]}=uniform({min(value, other)!r},{max(value, other)!r})"
                if not (math.isnan(value) or math.isnan(other)) else f"{option[7:]}={value!r}"]
    elif option == "--wind":
        argv = [f"--wind={value!r},{other!r},0"]
    else:
        argv = [f"{option}={value!r}"]
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        code = campaign.main(["--mission", "study", "--method", "none", "--runs", "2", "--hold", "0.2",
                              "--no-plots", "--quiet", *argv, "--out", str(Path(folder) / "c")])
        err = capsys.readouterr().err
        assert code in (2, 130), (code, err)
        assert "Traceback" not in err and len([x for x in err.splitlines() if x.strip()]) == 1, err
        assert time.perf_counter() - start < TIME_BOUND
