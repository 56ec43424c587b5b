"""A campaign's folder: finished runs stored as they finish, so that a campaign can resume.

Layout of the folder (``--out``)::

    campaign.json      the campaign (its key, the distributions, the mission, fpr's version)
    campaign.toml      the campaign as a file ``--campaign`` accepts back (its mission: mission.toml)
    mission.toml       the mission as planned
    runs/000042.json   one small file per finished run: its row
    runs.parquet       every row, by index (written at the end)
    summary.json       success rate with its 95 % Wilson interval, outcome distributions, timings
    *.png              the figures

Every file is written to a temporary name in the same folder and renamed into place (atomic on POSIX):
a run file is either complete or absent, whatever kills the process. A folder belongs to one campaign
(:meth:`fpr.robustness.spec.Campaign.key`): opening it for another campaign is refused, and a folder that
holds something else than a campaign is never written into.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from fpr.files import write_atomic
from fpr.model.errors import CampaignError

CAMPAIGN = "campaign.json"
RUNS = "runs"


def _jsonable(row: dict) -> dict:
    """NaN as null (strict JSON)."""
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()}


def _from_json(row: dict) -> dict:
    return {k: (math.nan if v is None else v) for k, v in row.items()}


class RunStore:
    """The finished runs of one campaign in its folder.

    Attributes:
        folder: the campaign's folder.
        key: the campaign's key (:meth:`fpr.robustness.spec.Campaign.key`).
    """

    def __init__(self, folder, key: str, description: dict):
        """Open (create) ``folder`` for the campaign ``key``; ``description`` goes into ``campaign.json``.

        Raises:
            CampaignError: ``folder`` is a file, holds something else than a campaign, or another campaign.
        """
        self.folder = Path(folder)
        self.key = key
        if self.folder.exists() and not self.folder.is_dir():
            raise CampaignError(f"--out {self.folder}", "is a file: give the path of a folder (it is created)")
        marker = self.folder / CAMPAIGN
        if self.folder.is_dir() and any(self.folder.iterdir()):
            if not marker.is_file():
                raise CampaignError(f"--out {self.folder}", "holds something else than a campaign (no "
                                                            "campaign.json): give a new or empty folder")
            try:
                previous = json.loads(marker.read_text(encoding="utf-8")).get("key")
            except (ValueError, OSError, AttributeError):
                previous = None
            if previous != key:
                raise CampaignError(f"--out {self.folder}", "holds another campaign (other mission, seed, "
                                                            "distributions or parameters): give another --out, "
                                                            "or delete the folder to start again")
        (self.folder / RUNS).mkdir(parents=True, exist_ok=True)
        write_atomic(marker, json.dumps({"key": key, **description}, indent=1, sort_keys=True) + "\n")

    def path(self, index: int) -> Path:
        """The file of run ``index``."""
        return self.folder / RUNS / f"{index:06d}.json"

    def put(self, row: dict) -> None:
        """Store a finished run's row (atomically)."""
        write_atomic(self.path(row["index"]), json.dumps(_jsonable(row), sort_keys=True))

    def load(self, runs: int) -> dict[int, dict]:
        """The stored rows of runs 0 .. runs - 1, by index (a file that cannot be read is left out: redone)."""
        rows = {}
        for index in range(runs):
            path = self.path(index)
            if not path.is_file():
                continue
            try:
                row = _from_json(json.loads(path.read_text(encoding="utf-8")))
            except (ValueError, OSError):
                continue
            if row.get("index") == index:
                rows[index] = row
        return rows
