"""Shared synthetic case files (built once per session)."""

import pytest

from analysis import detect, open_case

from . import synthetic


@pytest.fixture(scope="session")
def default_file(tmp_path_factory):
    """The 22.5 s default-like synthetic case, written to NetCDF4 like the engine's output."""
    path = tmp_path_factory.mktemp("cases") / "default.nc"
    synthetic.write(synthetic.default_case(), path)
    return path


@pytest.fixture(scope="session")
def default_case(default_file):
    return open_case(default_file)


@pytest.fixture(scope="session")
def default_slugs(default_case):
    return detect(default_case)
