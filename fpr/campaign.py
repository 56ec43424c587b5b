"""``python -m fpr.campaign``: the command line of :mod:`fpr.cli.campaign`."""

from fpr.cli.campaign import main

if __name__ == "__main__":
    raise SystemExit(main())
