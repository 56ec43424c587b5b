"""The thesis' planning studies with the toolkit's parameters (:mod:`fpr.studies.thesis`).

``python -m fpr.studies`` runs them (:mod:`fpr.cli.studies`).
"""
