"""``python -m fpr.bench`` and the console script ``fpr-bench``: the command line of :mod:`fpr.cli.bench`.

Ctrl-C and SIGTERM are handled from the first instruction, through the imports (:mod:`fpr.cli.launch`).
"""


def main(argv=None) -> None:
    """The process's entry point: ends the process with the exit code (at once after Ctrl-C: 130)."""
    from fpr.cli.launch import finish, launch

    finish(launch(None, "fpr.cli.bench:main", argv))


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:  # in the microseconds before fpr.cli.launch took over: still one line, 130
        import sys

        sys.stderr.write("interrupted (Ctrl-C or SIGTERM)\n")
        raise SystemExit(130) from None
