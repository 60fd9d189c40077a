"""The committed calibration example (docs/reference/calibration/, made by `snakemake -j2 calibration
--configfile config/calibration.yaml` and `calibration_reference`): its overlay applies to the base
case, and its fit agrees with the configuration and the measurements it was made from."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "docs/reference/calibration"


def test_the_committed_overlay_applies_to_the_vertical_base_case():
    check = subprocess.run([sys.executable, "-m", "engine.cli", "check", "config/cases/vertical.yaml",
                            "--overlay", str(REFERENCE / "fitted.yaml")], cwd=ROOT, capture_output=True, text=True)
    assert check.returncode == 0, check.stderr
    overlay = yaml.safe_load((REFERENCE / "fitted.yaml").read_text())["all_cases"]
    assert overlay["wall.friction"] == overlay["particles.friction"]  # same_as


def test_the_committed_fit_lies_inside_the_configured_box_and_matches_its_overlay():
    section = yaml.safe_load((ROOT / "config/calibration.yaml").read_text())["calibration"]
    fitted = json.loads((REFERENCE / "fitted.json").read_text())
    overlay = yaml.safe_load((REFERENCE / "fitted.yaml").read_text())["all_cases"]
    assert fitted["measurements"] == section["measurements"] and fitted["keys"] == list(section["fit"])
    assert fitted["at_bound"] == []
    for key, (low, high) in section["fit"].items():
        value, std = fitted["parameters"][key]["value"], fitted["parameters"][key]["std"]
        assert low < value < high and 0 < std < (high - low) / 2, key
        assert overlay[key] == pytest.approx(value, rel=5e-4)  # the overlay rounds to 4 digits
    # the table's measured column is the measurement file's series B
    table = (REFERENCE / "table.md").read_text()
    assert "| B | pressure_drop | 45 ± 2 hPa/m |" in table


def test_the_committed_prediction_is_of_the_configured_points_with_the_fits_error_bars():
    import numpy as np
    import pandas as pd

    from analysis.measurements import read_measurements, targets

    config = yaml.safe_load((ROOT / "config/calibration.yaml").read_text())
    measured = targets(read_measurements(ROOT / config["prediction"]["measurements"]))
    table = pd.read_csv(REFERENCE / "prediction/table.csv", comment="#")
    assert list(zip(table["label"], table["quantity"])) == list(zip(measured["label"], measured["quantity"]))
    np.testing.assert_allclose(table[["value", "error"]], measured[["value", "error"]])
    assert set(table["label"]) == {"A", "C"}  # series B, the fit's, is not predicted
    assert (table["predicted"] > 0).all() and (table["predicted_std"] > 0).all()
    pulls = (table["predicted"] - table["value"]) / np.hypot(table["error"], table["predicted_std"])
    np.testing.assert_allclose(table["pull"], pulls)
    fitted = json.loads((REFERENCE / "fitted.json").read_text())
    first = next(iter(fitted["parameters"].values()))
    assert f"{first['value']:.4g} ± {first['std']:.2g}" in (REFERENCE / "prediction/table.md").read_text()
    assert (REFERENCE / "prediction/predicted.png").stat().st_size > 0
