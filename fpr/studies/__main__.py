"""``python -m fpr.studies`` and the console script ``fpr-studies``: the command line of :mod:`fpr.cli.studies`.

Ctrl-C and SIGTERM are handled from the first instruction, through the imports (:mod:`fpr.cli.launch`).
"""


def main(argv=None) -> int:
    """The process's entry point: returns the exit code, or ends the process at once after Ctrl-C (130)."""
    from fpr.cli.launch import finish, launch

    finish(launch(None, "fpr.cli.studies:main", argv))


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:  # in the microseconds before fpr.cli.launch took over: still one line, 130
        import sys

        sys.stderr.write("interrupted (Ctrl-C or SIGTERM)\n")
        raise SystemExit(130) from None
