"""``python -m fpr.cli.bench``: the same as ``python -m fpr.bench``."""

from fpr.cli.bench.cli import main

raise SystemExit(main())
