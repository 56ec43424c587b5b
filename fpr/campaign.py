"""``python -m fpr.campaign`` and the console script ``fpr-campaign``: the command line of :mod:`fpr.cli.campaign`.

Ctrl-C and SIGTERM are handled from the first instruction (:mod:`fpr.cli.launch`); the options are parsed
(:mod:`fpr.cli.campaign_options`) before the planner, the simulator and Dask are imported. The local
cluster's worker processes re-import this module (Python's ``spawn``): there it only starts the watch that
ends such a process as soon as the campaign's process is gone (:mod:`fpr.cli.workers`).
"""


def main(argv=None) -> None:
    """The process's entry point: ends the process with the exit code (at once after Ctrl-C: 130).

    In a program of your own, call :func:`fpr.cli.campaign.main` instead: it returns in every case.
    """
    from fpr.cli.launch import finish, launch

    finish(launch("fpr.cli.campaign_options:parser", "fpr.cli.campaign:work", argv))


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:  # in the microseconds before fpr.cli.launch took over: still one line, 130
        import sys

        sys.stderr.write("interrupted (Ctrl-C or SIGTERM)\n")
        raise SystemExit(130) from None
elif __name__ == "__mp_main__":  # a worker process of the local cluster, starting
    from fpr.cli.workers import watch_parent

    watch_parent()
