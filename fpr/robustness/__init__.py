"""Robustness campaigns: one plan flown many times under sampled perturbations, on Dask.

:mod:`~fpr.robustness.spec` (the campaign and its distributions), :mod:`~fpr.robustness.campaign_file`
(campaign TOML files), :mod:`~fpr.robustness.outcomes` (one run and its row),
:mod:`~fpr.robustness.runner` (the runs on a Dask cluster), :mod:`~fpr.robustness.store` (the folder, one
file per finished run: resumable), :mod:`~fpr.robustness.summary` (table, success rate, Wilson interval).
The command line is :mod:`fpr.cli.campaign` (``python -m fpr.campaign``).
"""
