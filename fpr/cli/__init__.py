"""The applications: command lines on top of every other layer (``fpr-plan``, ``fpr-bench``, ``fpr-studies``).
Argument parsing, files and exit codes live here; the work is done by the layers below.
"""
