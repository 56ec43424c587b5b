"""A robustness campaign: what to fly, how many times, and the distributions of the perturbations.

A :class:`Campaign` names a mission (built-in or file), the planning method, the number of runs, a seed and,
for each perturbed quantity, a :class:`Distribution`. The quantities are those of
:class:`fpr.sim.closed_loop.SimulationSettings` and the robot's own parameters:

=========================== ========================================================================
name                        meaning
=========================== ========================================================================
``model_mass_scale``        the controller believes every mass times this (``--model-mass-scale``)
``rotor_constant_scale``    the plant's rotors give this times the nominal force (``--rotor-constant-scale``)
``wind_x/_y/_z``            constant wind force on each drone, world frame [N]; ``wind`` = all three
``noise_q``, ``noise_v``    measurement-noise standard deviations; ``noise`` = both
``initial_error.<coord>``   offset of a coordinate at the start [m or rad] (``--initial-error``)
``<robot parameter>``       a xacro argument ``--set`` accepts (``link_length``, ``drone_mass``...): the
                            robot that flies the plan is built with it (the plan is not remade; the
                            controller is told the robot's parameters; ``model_mass_scale`` gives it a
                            wrong belief)
=========================== ========================================================================

Distributions are written as in ``--vary``: ``uniform(lo, hi)``, ``normal(mean, sd)``,
``truncnormal(mean, sd, lo, hi)``, ``lognormal(median, sigma)`` (median times exp(sigma N(0,1))),
``loguniform(lo, hi)``, ``choice(a, b, ...)``, ``linspace(lo, hi)`` (run i of N gets
lo + (hi - lo) i / (N - 1): a sweep), or a plain number (a constant). A vector quantity (``wind``,
``noise``) takes one distribution per component: ``wind=normal(0, 1)`` draws each axis independently
from N(0, 1); ``wind=normal([0, 2, 0], [1, 1, 0.5])`` gives each axis its own parameters.

**Event families** (``events = "move"`` or ``"gust"``, :mod:`fpr.robustness.events`): each run also gets one
random event (a way point that moves, a gust), drawn from ``spawn_key=(i, 2)``, with the family's options
(``event_options``), flown with the replanner (``replan``) and, with ``without_observer``, also by the
controller without its observer; a move's run succeeds when the robot passes within ``pass_tolerance`` of the
moved way point, a gust's when the robot is not lost, breaks no physical limit and has at most
``max_saturation`` of its ticks saturated (:mod:`fpr.robustness.outcomes`).

Determinism: run ``i`` draws its values from ``numpy.random.SeedSequence(seed, spawn_key=(i, 0))`` and its
measurement noise from ``spawn_key=(i, 1)``: the children ``SeedSequence(seed).spawn`` would give, made
directly from the run's index. A run's values therefore depend only on the campaign and its index, never on
the number of workers or the order in which runs finish.
"""

from __future__ import annotations

import ast
import dataclasses
import hashlib
import json
import math
import re
from dataclasses import dataclass, field

import numpy as np

from fpr.model.errors import CampaignError
from fpr.robots import PARAMETER_RANGES
from fpr.robustness.events import family

VECTORS = {"wind": ("wind_x", "wind_y", "wind_z"), "noise": ("noise_q", "noise_v")}
"""Vector quantities and their components (columns of the table)."""
SETTINGS = ("model_mass_scale", "rotor_constant_scale", *VECTORS["wind"], *VECTORS["noise"])
"""Scalar quantities of :class:`fpr.sim.closed_loop.SimulationSettings` a campaign can vary."""
INITIAL_ERROR = "initial_error."
"""Prefix of an initial-error quantity: ``initial_error.<coordinate>``."""
KINDS = {"uniform": 2, "normal": 2, "truncnormal": 4, "lognormal": 2, "loguniform": 2, "linspace": 2,
         "choice": None, "constant": 1}
"""Distribution kinds and their number of parameters (None: one or more)."""
_CALL = re.compile(r"^\s*([a-z_]+)\s*\((.*)\)\s*$", re.S)


@dataclass(frozen=True)
class Distribution:
    """One scalar distribution.

    Attributes:
        kind: a key of :data:`KINDS`.
        params: its parameters, in the order the text gives them.
    """

    kind: str
    params: tuple[float, ...]

    def __post_init__(self):
        wanted = KINDS.get(self.kind, -1)
        text = self.text()
        if wanted == -1:
            raise CampaignError(text, f"unknown distribution {self.kind!r}: use one of {', '.join(KINDS)}")
        if (wanted is None and not self.params) or (wanted is not None and len(self.params) != wanted):
            raise CampaignError(text, f"{self.kind} takes {wanted or 'one or more'} number(s), "
                                      f"{len(self.params)} given")
        if not all(math.isfinite(p) for p in self.params):
            raise CampaignError(text, "give finite numbers")
        p = self.params
        if self.kind in ("uniform", "loguniform", "linspace") and p[0] > p[1]:
            raise CampaignError(text, "give the lower bound first (lo <= hi)")
        if self.kind in ("normal", "truncnormal", "lognormal") and p[1] < 0:
            raise CampaignError(text, "a standard deviation is >= 0")
        if self.kind == "truncnormal" and not p[2] <= p[3]:
            raise CampaignError(text, "give the truncation bounds as lo <= hi")
        if self.kind == "truncnormal" and p[1] == 0 and not p[2] <= p[0] <= p[3]:
            raise CampaignError(text, "with sd 0 the mean must lie between the bounds")
        if self.kind in ("loguniform", "lognormal") and p[0] <= 0:
            raise CampaignError(text, f"{self.kind} needs a first parameter > 0")

    def text(self) -> str:
        """The distribution as ``--vary`` writes it (a constant: the plain number)."""
        if self.kind == "constant":
            return f"{self.params[0]!r}"
        return f"{self.kind}({', '.join(repr(float(v)) for v in self.params)})"

    def support(self) -> tuple[float, float]:
        """The values it can give: (least, largest), infinite for an unbounded distribution."""
        p = self.params
        if self.kind in ("uniform", "loguniform", "linspace"):
            return p[0], p[1]
        if self.kind == "truncnormal":
            return p[2], p[3]
        if self.kind in ("choice", "constant"):
            return min(p), max(p)
        if self.kind == "lognormal":
            return (p[0], p[0]) if p[1] == 0 else (0.0, math.inf)
        return (p[0], p[0]) if p[1] == 0 else (-math.inf, math.inf)

    def typical(self) -> float:
        """A value it gives typically (the mean, median or middle): what a check of its range looks at."""
        p = self.params
        if self.kind in ("normal", "lognormal", "constant"):
            return p[0]
        if self.kind == "truncnormal":
            return min(max(p[0], p[2]), p[3])
        if self.kind == "loguniform":
            return math.sqrt(p[0] * p[1])
        if self.kind == "choice":
            return p[0]
        return 0.5 * (p[0] + p[1])

    def draw(self, rng: np.random.Generator, index: int, runs: int) -> float:
        """One value for run ``index`` of ``runs``; ``rng`` is the run's own generator."""
        p = self.params
        if self.kind == "uniform":
            return float(rng.uniform(p[0], p[1]))
        if self.kind == "normal":
            return float(p[0] + p[1] * rng.standard_normal())
        if self.kind == "lognormal":
            return float(p[0] * math.exp(p[1] * rng.standard_normal()))
        if self.kind == "loguniform":
            return float(math.exp(rng.uniform(math.log(p[0]), math.log(p[1]))))
        if self.kind == "choice":
            return float(p[int(rng.integers(len(p)))])
        if self.kind == "linspace":
            return float(p[0] + (p[1] - p[0]) * (index / (runs - 1) if runs > 1 else 0.5))
        if self.kind == "truncnormal":
            return _truncated_normal(rng, *p)
        return float(p[0])


def _truncated_normal(rng, mean, sd, lo, hi) -> float:
    """N(mean, sd) restricted to [lo, hi], by the inverse of its CDF (one uniform number a draw)."""
    if sd == 0:
        return float(mean)
    from scipy.special import ndtr, ndtri

    a, b = ndtr((lo - mean) / sd), ndtr((hi - mean) / sd)
    if b - a < 1e-12:  # the interval is far in a tail: its nearer end
        return float(lo if mean < lo else hi)
    return float(min(max(mean + sd * ndtri(a + (b - a) * rng.uniform()), lo), hi))


def _numbers(value, text: str) -> list:
    """The parameters of a distribution: numbers or lists of numbers (vector parameters)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, list, tuple)):
        raise CampaignError(text, "give numbers, or [a, b, c] lists for the components of a vector")
    if isinstance(value, (list, tuple)):
        if not value or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise CampaignError(text, "a list holds numbers, one per component")
        return [float(v) for v in value]
    return float(value)


def parse_distribution(text, components: int = 1) -> list[Distribution]:
    """A distribution from its text (``"uniform(0.9, 1.1)"``, ``"0.5"``, ``"normal([0, 1, 0], 1)"``), or a
    number or list (TOML), one :class:`Distribution` per component of the quantity.

    Raises:
        CampaignError: a text that is not a distribution, an unknown kind, wrong parameters, or lists whose
            length is not the number of components.
    """
    if isinstance(text, (int, float, list)) and not isinstance(text, bool):
        kind, args, shown = "constant", [text], json.dumps(text)
    else:
        shown = str(text)
        match = _CALL.match(shown)
        try:
            if match:
                kind, args = match.group(1), list(ast.literal_eval(f"[{match.group(2)}]"))
            else:
                kind, args = "constant", [ast.literal_eval(shown.strip())]
        except (ValueError, SyntaxError, MemoryError, RecursionError):
            raise CampaignError(shown, "write a distribution like uniform(0.9, 1.1), normal(0, 1) or a "
                                       f"number; kinds: {', '.join(KINDS)}") from None
    params = [_numbers(a, shown) for a in args]
    for p in params:
        if isinstance(p, list) and len(p) != components:
            raise CampaignError(shown, f"a list gives one number per component: {components} here, "
                                       f"{len(p)} given")
    return [Distribution(kind, tuple(p[c] if isinstance(p, list) else p for p in params))
            for c in range(components)]


#: Units of the scalar settings a campaign varies ("1": a ratio).
SETTING_UNITS = {"model_mass_scale": "1", "rotor_constant_scale": "1", "wind_x": "N", "wind_y": "N", "wind_z": "N",
                 "noise_q": "m or rad", "noise_v": "m/s or rad/s"}
#: Units of the outcome columns that are not a coordinate's (``max_error_<coordinate>`` is the coordinate's).
OUTCOME_UNITS = {"least_clearance_m": "m", "saturated_ticks": "ticks", "peak_rotor_speed_rad_s": "rad/s"}


def coordinate_unit(coordinate: str) -> str:
    """The unit of a planning coordinate: "m" for a position (``x``, ``y``, ``z``), "rad" for an angle (``phi``,
    ``q21``, ``q1``...).
    """
    return "m" if coordinate in ("x", "y", "z") else "rad"


def unit(name: str) -> str:
    """The unit of a campaign column (a varied quantity or an outcome), for axis labels; "" when unknown."""
    if name in SETTING_UNITS:
        return SETTING_UNITS[name]
    if name in OUTCOME_UNITS:
        return OUTCOME_UNITS[name]
    if name.startswith(INITIAL_ERROR):
        return coordinate_unit(name[len(INITIAL_ERROR):])
    if name.startswith("max_error_"):
        return coordinate_unit(name[len("max_error_"):])
    if name in PARAMETER_RANGES:
        return PARAMETER_RANGES[name].unit
    return ""


def components(name: str) -> tuple[str, ...]:
    """The column names a quantity stands for (``wind`` -> wind_x, wind_y, wind_z; others: itself)."""
    return VECTORS.get(name, (name,))


@dataclass(frozen=True)
class Campaign:
    """What a campaign flies and how it perturbs it.

    Attributes:
        mission: a built-in mission name or the path of a mission TOML file.
        method: the planning method (a name of :data:`planners.methods.METHODS`); the plan is made once.
        runs: number of closed-loop runs (>= 1).
        seed: the campaign's seed (an integer >= 0).
        vary: quantity (column name, see the module docstring) -> :class:`Distribution`, one per column.
        robot_parameters: fixed robot parameters, for the plan and every run (as ``--set``).
        hold: time simulated after the plan's end [s].
        tracking_tolerance: a run succeeds only if every planning coordinate stays within this of the plan
            [m or rad]; None: a run succeeds when the robot is not lost (:mod:`fpr.sim.watch`).
        events: an event family (:data:`fpr.robustness.events.FAMILIES`), or None.
        event_options: the family's options (:class:`fpr.robustness.events.MoveFamily`,
            :class:`~fpr.robustness.events.GustFamily`).
        replan: fly with the replanner (needed for moves).
        without_observer: also fly each run with the controller without its observer (``no_observer_*``).
        pass_tolerance: a move's run succeeds within this of the moved way point [m].
        max_saturation: a gust's run succeeds with at most this share of saturated ticks.
    """

    mission: str = "square"
    method: str = "two-step"
    runs: int = 100
    seed: int = 0
    vary: dict = field(default_factory=dict)
    robot_parameters: dict = field(default_factory=dict)
    hold: float = 1.0
    tracking_tolerance: float | None = None
    events: str | None = None
    event_options: dict = field(default_factory=dict)
    replan: bool = False
    without_observer: bool = False
    pass_tolerance: float = 0.02
    max_saturation: float = 0.01

    def __post_init__(self):
        if isinstance(self.runs, bool) or not isinstance(self.runs, int) or self.runs < 1:
            raise CampaignError(f"runs = {self.runs!r}", "give a whole number of runs >= 1")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise CampaignError(f"seed = {self.seed!r}", "give a whole number >= 0")
        if not (isinstance(self.hold, (int, float)) and math.isfinite(self.hold) and self.hold >= 0):
            raise CampaignError(f"hold = {self.hold!r}", "give a time >= 0 [s]")
        tol = self.tracking_tolerance
        if tol is not None and not (isinstance(tol, (int, float)) and math.isfinite(tol) and tol > 0):
            raise CampaignError(f"tracking_tolerance = {tol!r}", "give a number > 0 [m or rad], or leave it out")
        for name, dist in self.vary.items():
            if not isinstance(dist, Distribution):
                raise CampaignError(f"{name}", "give a Distribution (parse_distribution makes one)")
        if self.events is not None:
            family(self.events, **self.event_options)  # refuses an unknown family or option
        elif self.event_options:
            raise CampaignError("event_options", "give an event family (events = \"move\" or \"gust\") first")
        for name in ("replan", "without_observer"):
            if not isinstance(getattr(self, name), bool):
                raise CampaignError(f"{name} = {getattr(self, name)!r}", "give true or false")
        for name, high in (("pass_tolerance", math.inf), ("max_saturation", 1.0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and 0 < value <= high):
                raise CampaignError(f"{name} = {value!r}", f"give a number in (0, {high:g}]")

    def with_vary(self, name: str, text) -> Campaign:
        """This campaign with quantity ``name`` (a component, a vector such as ``wind``, a robot parameter or
        ``initial_error.<coordinate>``) drawn from ``text`` (see :func:`parse_distribution`).
        """
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)?", name or ""):
            raise CampaignError(f"{name}={text}", "write NAME=DISTRIBUTION, e.g. model_mass_scale=uniform(0.9,1.1)")
        if "." in name and not name.startswith(INITIAL_ERROR):
            raise CampaignError(f"{name}={text}", f"only {INITIAL_ERROR}<coordinate> has a dot")
        names = components(name)
        try:
            dists = parse_distribution(text, len(names))
        except CampaignError as error:
            raise CampaignError(f"{name}={error.what}", error.reason) from None
        return dataclasses.replace(self, vary={**self.vary, **dict(zip(names, dists, strict=True))})

    @property
    def columns(self) -> tuple[str, ...]:
        """The varied columns, sorted: the order in which a run draws them."""
        return tuple(sorted(self.vary))

    def values(self, index: int) -> dict[str, float]:
        """The sampled values of run ``index`` (0-based), by column."""
        rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(index, 0)))
        return {name: self.vary[name].draw(rng, index, self.runs) for name in self.columns}

    def event_family(self):
        """The event family's generator (:func:`fpr.robustness.events.family`), or None."""
        return None if self.events is None else family(self.events, **self.event_options)

    def noise_seed(self, index: int) -> int:
        """The measurement-noise seed of run ``index`` (from the campaign's seed and the index)."""
        return int(np.random.SeedSequence(self.seed, spawn_key=(index, 1)).generate_state(1)[0])

    def key(self, mission_toml: str) -> str:
        """SHA-256 of what a run's row depends on: the mission as planned, the method, the seed, the
        distributions, the fixed parameters, hold and tolerance (not ``runs``, unless a ``linspace`` makes
        the values depend on it: a campaign can then grow and keep its runs).
        """
        document = {"mission": mission_toml, "method": self.method, "seed": self.seed, "hold": self.hold,
                    "tracking_tolerance": self.tracking_tolerance, "robot_parameters": self.robot_parameters,
                    "vary": {k: self.vary[k].text() for k in self.columns}}
        if any(d.kind == "linspace" for d in self.vary.values()):
            document["runs"] = self.runs
        if self.events is not None:  # (absent otherwise: the keys of campaigns without events are unchanged)
            document.update(events=self.events, event_options=self.event_options, replan=self.replan,
                            without_observer=self.without_observer, pass_tolerance=self.pass_tolerance,
                            max_saturation=self.max_saturation)
        elif self.replan or self.without_observer:
            document.update(replan=self.replan, without_observer=self.without_observer)
        text = json.dumps(document, sort_keys=True)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()
