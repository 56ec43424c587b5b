"""``python -m fpr.studies``: the command line of :mod:`fpr.cli.studies`."""

from fpr.cli.studies import main

if __name__ == "__main__":
    raise SystemExit(main())
