"""Regression baselines (tests/regression/cases.py; regenerate: python -m tests.regression.regenerate)."""
