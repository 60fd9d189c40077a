"""Tests of the one-off study scripts in benchmarks/studies/."""
