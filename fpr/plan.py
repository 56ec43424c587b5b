"""``python -m fpr.plan`` and the console script ``fpr-plan``: the command line of :mod:`fpr.cli.plan`.

Ctrl-C and SIGTERM are handled from the first instruction (:mod:`fpr.cli.launch`); the options are parsed
(:mod:`fpr.cli.plan_options`) before the planner and the simulator are imported.
"""


def main(argv=None) -> None:
    """The process's entry point: ends the process with the exit code (at once after Ctrl-C: 130).

    In a program of your own, call :func:`fpr.cli.plan.main` instead: it returns in every case.
    """
    from fpr.cli.launch import finish, launch

    finish(launch("fpr.cli.plan_options:parser", "fpr.cli.plan:work", argv))


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:  # in the microseconds before fpr.cli.launch took over: still one line, 130
        import sys

        sys.stderr.write("interrupted (Ctrl-C or SIGTERM)\n")
        raise SystemExit(130) from None
