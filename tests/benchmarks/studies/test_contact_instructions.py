"""benchmarks/studies/contact_instructions.py: the variant modules it writes are the loop, its parsing of
valgrind's count, its clock and its refusals (no valgrind run: one loop compiled, about 15 s)."""

import sys

import numpy as np
import pytest

from engine.kernels import contacts

from .. import load_benchmark
from . import small_conveying_simulation


@pytest.fixture(scope="module")
def study():
    return load_benchmark("studies/contact_instructions")


def test_a_written_variant_module_is_the_engines_loop_bit_for_bit(study, tmp_path, monkeypatch):
    where = study.write_variant(tmp_path, "engine")
    monkeypatch.syspath_prepend(str(where))
    for name in ("ablation_loop", "ablation_laws"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    from ablation_loop import loop

    sim = small_conveying_simulation()
    n, grains = sim.n_particles, sim._grains()
    arguments = (0, n, grains, sim._nbr_start, sim._nbr, sim._p, grains.force, grains.torque,
                 grains.viscous_damping, sim._nbr_start[:0])
    written = loop(*arguments)
    force, torque = grains.force[:n].copy(), grains.torque[:n].copy()
    assert contacts._contacts_range_plain(*arguments) == written
    assert np.abs(force).max() > 0 and np.array_equal(force, grains.force[:n])
    assert np.array_equal(torque, grains.torque[:n])


def test_valgrinds_count_is_read_with_its_thousands_separators(study):
    line = "==20506== I   refs:      3,717,954,041\n==20506== Branches: 626,754,233"
    assert int(study.REFS.search(line).group(1).replace(",", "")) == 3_717_954_041


def test_the_clock_is_a_cores_clock(study):
    # the chain's 4 cycles per link: a chain folded by the compiler would give tens of GHz
    assert 0.5e9 < study.clock_hz(chain=20_000_000) < 7e9


def test_unknown_variants_and_a_missing_valgrind_are_refused_before_any_work(study, monkeypatch, capsys):
    with pytest.raises(SystemExit):
        study.main(["--variants", "engine", "no_such"])
    assert "unknown no_such" in capsys.readouterr().err
    monkeypatch.setattr(study.shutil, "which", lambda name: None)
    with pytest.raises(SystemExit, match="valgrind is not on PATH"):
        study.main(["--variants", "engine"])
