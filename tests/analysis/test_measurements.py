"""The measurement file of a rig: reading, the checks that name line and column, the targets."""

import math
from pathlib import Path

import pytest

from analysis.measurements import (MeasurementFileError, read_measurements, superficial_velocity,
                                   targets)

ROOT = Path(__file__).resolve().parents[2]
HEADER = ("label,orientation,tube_length_m,tube_diameter_m,particle_diameter_m,particle_density_kg_m3,"
          "gas_flow_l_min,mass_flow_kg_h,pressure_drop_hPa_m,pressure_drop_error_hPa_m,"
          "plug_velocity_min_m_s,plug_velocity_max_m_s")
GOOD = "B,vertical,1.01,0.007,0.0014,937,2.2,2.49,45,2,0.12,0.19"


def write(tmp_path, *rows, header=HEADER):
    path = tmp_path / "rig.csv"
    path.write_text("# a comment line\n" + "\n".join([header, *rows]) + "\n")
    return path


def test_superficial_velocity_is_the_volume_flow_over_the_tube_section():
    # 2.3 l/min in a 7 mm tube: the vertical paper's v_s = 1 m/s (V §4, 4 V / (pi D^2) = 0.996 m/s)
    assert superficial_velocity(2.3, 0.007) == pytest.approx(0.9961, abs=1e-4)


def test_shipped_example_reads_with_velocity_and_si_targets():
    points = read_measurements(ROOT / "resources/measurements/vertical_series_B.csv")
    assert list(points.index) == ["B"]
    assert points.loc["B", "superficial_velocity_m_s"] == pytest.approx(superficial_velocity(2.2, 0.007))
    t = targets(points).set_index("quantity")
    assert t.loc["pressure_drop", "value"] == 4500.0 and t.loc["pressure_drop", "error"] == 200.0  # Pa/m
    # a range enters as its midpoint, with the standard deviation of a uniform spread over it
    assert t.loc["plug_length", "value"] == pytest.approx(0.0535)
    assert t.loc["plug_length", "error"] == pytest.approx((0.09 - 0.017) / 2 / math.sqrt(3))
    assert t.loc["plug_velocity", "summary_key"] == "slug_velocity"


def test_superficial_velocity_column_is_taken_as_given(tmp_path):
    header = HEADER.replace("gas_flow_l_min", "superficial_velocity_m_s")
    points = read_measurements(write(tmp_path, GOOD.replace(",2.2,", ",0.8,"), header=header))
    assert points.loc["B", "superficial_velocity_m_s"] == 0.8


def test_optional_ranges_may_be_left_out(tmp_path):
    header = HEADER.rsplit(",", 2)[0]
    points = read_measurements(write(tmp_path, GOOD.rsplit(",", 2)[0], header=header))
    assert list(targets(points)["quantity"]) == ["pressure_drop"]


@pytest.mark.parametrize("row, line, column, words", [
    (GOOD.replace(",2,", ",-2,"), 3, "pressure_drop_error_hPa_m", "> 0"),
    (GOOD.replace("vertical", "upward"), 3, "orientation", "horizontal, vertical"),
    (GOOD.replace(",45,", ",lots,"), 3, "pressure_drop_hPa_m", "not a number"),
    (GOOD.replace(",0.19", ",0.10"), 3, "plug_velocity_max_m_s", "larger than plug_velocity_min_m_s"),
    (GOOD.replace(",0.19", ","), 3, "plug_velocity_max_m_s", "both"),
    (GOOD.replace(",0.0014,", ",0.008,"), 3, "particle_diameter_m", "smaller than tube_diameter_m"),
    (GOOD.replace(",1.01,", ",,"), 3, "tube_length_m", "required"),
])
def test_bad_value_names_line_label_and_column(tmp_path, row, line, column, words):
    with pytest.raises(MeasurementFileError) as err:
        read_measurements(write(tmp_path, row))
    message = str(err.value)
    assert f"line {line} (label B), column {column}" in message and words in message


def test_second_row_errors_name_that_row(tmp_path):
    with pytest.raises(MeasurementFileError, match=r"line 4 \(label B\), column label: 'B' is already"):
        read_measurements(write(tmp_path, GOOD, GOOD))
    with pytest.raises(MeasurementFileError, match=r"line 4 \(label C\), column particle_density_kg_m3: one material"):
        read_measurements(write(tmp_path, GOOD, GOOD.replace("B,", "C,").replace(",937,", ",1000,")))


def test_gas_flow_needs_exactly_one_of_its_two_columns(tmp_path):
    header = HEADER + ",superficial_velocity_m_s"
    with pytest.raises(MeasurementFileError, match="gas_flow_l_min or superficial_velocity_m_s: give exactly one"):
        read_measurements(write(tmp_path, GOOD + ",0.9", header=header))


def test_unknown_and_missing_columns_are_refused(tmp_path):
    with pytest.raises(MeasurementFileError, match="line 2: unknown column 'pressure_drop_hpa_m'"):
        read_measurements(write(tmp_path, GOOD, header=HEADER.replace("pressure_drop_hPa_m", "pressure_drop_hpa_m")))
    header = HEADER.replace("mass_flow_kg_h,", "")
    with pytest.raises(MeasurementFileError, match="missing column 'mass_flow_kg_h'"):
        read_measurements(write(tmp_path, GOOD.replace(",2.49,", ","), header=header))
    with pytest.raises(MeasurementFileError, match="no operating points"):
        read_measurements(write(tmp_path))
