"""``python -m fpr.plan``: the command line of :mod:`fpr.cli.plan`."""

from fpr.cli.plan import main

if __name__ == "__main__":
    raise SystemExit(main())
