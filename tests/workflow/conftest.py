"""Workflow tests. The `workflow` marker (pyproject.toml) selects the full reduced-config run
(about 2 min on 2 cores); it is part of the default test run, deselect it with -m "not workflow"."""
