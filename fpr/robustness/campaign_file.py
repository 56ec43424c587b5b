"""Campaign files: a campaign as TOML, to keep with a paper and run again (``--campaign FILE``).

Every field is optional (defaults of :class:`fpr.robustness.spec.Campaign`)::

    mission = "square"          # a built-in mission, or a mission file (a relative path: from this file)
    method = "two-step"         # planning method; the plan is made once
    runs = 200                  # closed-loop runs
    seed = 1                    # run i draws from SeedSequence(seed, spawn_key=(i, 0))
    hold = 1.0                  # time simulated after the plan's end [s]
    tracking_tolerance = 0.05   # optional: a run succeeds only within this of the plan [m or rad]

    [robot_parameters]          # fixed, for the plan and every run (as --set)
    link_length = 0.75

    [vary]                      # quantity = distribution (as --vary NAME=DISTRIBUTION), or a number
    model_mass_scale = "uniform(0.9, 1.1)"
    rotor_constant_scale = "normal(1, 0.03)"
    wind = "normal(0, 1)"       # each axis; or wind_y = ..., or normal([0, 1, 0], [1, 1, 0.5])
    noise = [0.001, 0.01]       # constants: sd on q and on v
    "initial_error.y" = "normal(0, 0.02)"
    drone_mass = "uniform(0.95, 1.05)"

An event family (:mod:`fpr.robustness.events`), optional::

    events = "gust"             # or "move": one random event per run
    replan = false              # fly with the replanner (moves need it)
    without_observer = true     # the same runs by the controller without its observer, beside
    max_saturation = 0.01       # a gust's run succeeds with at most this share of saturated ticks
    pass_tolerance = 0.02       # a move's run succeeds within this of the moved way point [m]

    [event_options]             # the family's options
    force = [0.0, 8.0]          # gust: strength [N]; rise, duration [s]; bodies ("all", "end_effector", "drones")
    # distance = [0.05, 0.3]    # move: displacement [m]; warning [s] before the way point

:func:`campaign_to_toml` writes one back (the folder's ``campaign.toml``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from fpr.model.errors import CampaignError
from fpr.robustness.spec import Campaign

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

FIELDS = ("mission", "method", "runs", "seed", "hold", "tracking_tolerance", "events", "replan", "without_observer",
          "pass_tolerance", "max_saturation", "robot_parameters", "vary", "event_options")
SCALARS = FIELDS[:11]


def load_campaign(path) -> Campaign:
    """Read a campaign file.

    Raises:
        CampaignError: a file that cannot be read, is not TOML, has an unknown field or a wrong value (the
            message names the file and the field).
    """
    path = Path(path)
    try:
        document = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as error:
        raise CampaignError(str(path), f"cannot read the campaign file ({error}): give the path of a .toml "
                                       "campaign file") from None
    except tomllib.TOMLDecodeError as error:
        raise CampaignError(str(path), f"not TOML: {error}") from None
    return campaign_from_dict(document, path)


def campaign_from_dict(document: dict, path=None) -> Campaign:
    """A campaign from the fields of a campaign file (``path``: the file, for messages and relative missions)."""
    where = str(path) if path is not None else "campaign"
    unknown = sorted(set(document) - set(FIELDS))
    if unknown:
        raise CampaignError(f"{where}: field {unknown[0]!r}", f"unknown field: use {', '.join(FIELDS)}")
    fields = {k: document[k] for k in SCALARS if k in document}
    mission = fields.get("mission")
    if mission is not None:
        if not isinstance(mission, str):
            raise CampaignError(f"{where}: field 'mission'", "give a built-in mission name or a file path")
        local = Path(path).parent / mission if path is not None else None
        if local is not None and mission.endswith(".toml") and not Path(mission).is_absolute():
            fields["mission"] = str(local)
    for key in ("robot_parameters", "vary", "event_options"):
        if not isinstance(document.get(key, {}), dict):
            raise CampaignError(f"{where}: field {key!r}", "give a table ([" + key + "])")
    parameters = document.get("robot_parameters", {})
    for key, value in parameters.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise CampaignError(f"{where}: field 'robot_parameters.{key}'", "give a number [SI units]")
    try:
        campaign = Campaign(**fields, robot_parameters={k: float(v) for k, v in parameters.items()},
                            event_options=dict(document.get("event_options", {})))
        for name, text in document.get("vary", {}).items():
            campaign = campaign.with_vary(name, text)
    except CampaignError as error:
        raise CampaignError(f"{where}: {error.what}", error.reason) from None
    except TypeError as error:
        raise CampaignError(where, f"a field of the wrong type ({error})") from None
    return campaign


def _value(value) -> str:
    return json.dumps(value)


def campaign_to_toml(campaign: Campaign, mission: str | None = None) -> str:
    """The campaign as a campaign file (``mission``: what to write as its mission, default the campaign's)."""
    lines = ["# fpr robustness campaign: python -m fpr.campaign --campaign campaign.toml",
             f"mission = {_value(mission or campaign.mission)}",
             f"method = {_value(campaign.method)}",
             f"runs = {campaign.runs}",
             f"seed = {campaign.seed}",
             f"hold = {float(campaign.hold)!r}"]
    if campaign.tracking_tolerance is not None:
        lines.append(f"tracking_tolerance = {float(campaign.tracking_tolerance)!r}")
    if campaign.events is not None:
        lines += [f"events = {_value(campaign.events)}", f"pass_tolerance = {float(campaign.pass_tolerance)!r}",
                  f"max_saturation = {float(campaign.max_saturation)!r}"]
    if campaign.events is not None or campaign.replan or campaign.without_observer:
        lines += [f"replan = {_value(campaign.replan)}", f"without_observer = {_value(campaign.without_observer)}"]
    lines += ["", "[robot_parameters]"]
    lines += [f"{k} = {float(v)!r}" for k, v in sorted(campaign.robot_parameters.items())]
    lines += ["", "[vary]"]
    lines += [f"{_value(k)} = {_value(campaign.vary[k].text())}" for k in campaign.columns]
    if campaign.event_options:
        lines += ["", "[event_options]"]
        lines += [f"{k} = {_value(v)}" for k, v in sorted(campaign.event_options.items())]
    return "\n".join(lines) + "\n"
