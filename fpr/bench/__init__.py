"""Benchmarking library: families of missions to plan, and the thesis-like baseline planner.

``python -m fpr.bench`` runs the benchmark (:mod:`fpr.cli.bench`).
"""
