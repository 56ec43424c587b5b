"""``python -m fpr.bench``: the command line of :mod:`fpr.cli.bench`."""

from fpr.cli.bench import main

if __name__ == "__main__":
    raise SystemExit(main())
