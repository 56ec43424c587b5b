"""The optional parts of fpr (``pyproject.toml``'s extras), and the one-line hint when one is missing.

The core (``pip install -e .``) runs ``python -m fpr.plan`` with ``--simulate`` and ``--meshcat``, the studies
and the bench. The campaigns (``python -m fpr.campaign``: Dask and pyarrow), the notebooks' widgets and the
test suite are extras: ``pip install -e '.[campaign]'``, ``'.[notebooks]'``, ``'.[test]'`` (the test extra
includes what the tests of the campaigns and of the notebooks run).
"""

from __future__ import annotations

import importlib.util

from fpr.model.errors import FprError

#: The modules each extra brings that fpr imports, by extra.
EXTRAS = {
    "campaign": ("distributed", "pyarrow"),
    "notebooks": ("ipywidgets", "nbclient", "ipykernel"),
}


class MissingExtraError(FprError, ImportError):
    """An optional part of fpr was asked for without its extra installed.

    Attributes:
        extra: the extra's name (``pyproject.toml``).
        missing: the modules that could not be found.
    """

    def __init__(self, extra: str, missing: tuple[str, ...]):
        self.extra = extra
        self.missing = tuple(missing)
        super().__init__(f"install the {extra} extra: pip install -e '.[{extra}]' (missing: {', '.join(self.missing)})")


def missing(extra: str, modules: tuple[str, ...] | None = None) -> tuple[str, ...]:
    """The modules of ``extra`` (default :data:`EXTRAS`) that are not installed (found without importing them)."""
    names = EXTRAS[extra] if modules is None else modules
    return tuple(name for name in names if importlib.util.find_spec(name) is None)


def require(extra: str, modules: tuple[str, ...] | None = None) -> None:
    """Raise :class:`MissingExtraError` when a module of ``extra`` (default :data:`EXTRAS`) is not installed."""
    absent = missing(extra, modules)
    if absent:
        raise MissingExtraError(extra, absent)
