"""The regression cases: small runs whose key outputs are stored in tests/regression/baselines/.

Each case is a function returning {quantity: value}; TOLERANCES says, per quantity, how far a
result may move from its baseline, and why (the measured gaps are in the comments).

    packed_bed   grains dropped into a 2.1 cm horizontal tube (gas and feed off), settled
    horizontal   config/cases/horizontal.yaml in a 2.1 cm tube (6 gas nodes), from empty
    vertical     config/cases/vertical.yaml in the same short tube
    reduction    the workflow's per-case reduction (analysis: detect, slug_statistics,
                 case_summary) of the horizontal case file and of a synthetic case file

The cases run through engine.run.run_case (the path of `plugsim run`) or Simulation, in a child
process (`run_in_child`) whose numba cache is a folder named after a hash of the engine's numba
source (kernel_cache_dir), apart from the checkout's own cache: numba's own cache checks only the
file of each compiled function, so after a change to engine/kernels/laws.py, whose laws the
kernels of contacts.py and stepper.py inline, it loaded the old kernels and the regression test
passed on the old physics (measured: a 1 % change of k_n passed that way; the engine's cache is
now keyed on every kernel source too, docs/decisions/0023). `python -m tests.regression.cases OUT.json [CASE
...]` computes the cases in this process and writes their quantities as JSON.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
BASELINES = Path(__file__).resolve().parent / "baselines"

# A 2.1 cm tube (15 grain diameters, 6 gas nodes of 3.5 mm like the default 150 on 52.5 cm).
SHORT_TUBE = {"tube.length": 0.021, "gas.nodes_x": 6, "run.checkpoint_interval": 0.0}
DURATION = {"packed_bed": 0.15, "horizontal": 0.08, "vertical": 0.08}  # simulated s, see TOLERANCES


# ---- the cases ---------------------------------------------------------------------------------
def packed_bed(duration: float = DURATION["packed_bed"], case_overrides=(), sample_times=None) -> dict:
    """60 grains on a loose jittered lattice in the first 2 cm of a horizontal 3.5 cm tube fall and
    settle (gas and feed off; the pile spreads along the tube but none reaches the open outlet).
    Quantities at the end: the grains' mean and spread of height z and of x, the total normal force
    on the cylinder wall (from the slice wall stress), the largest overlap over the last 0.01 s and
    the kinetic energy."""
    from engine import Case, Simulation

    case = Case().with_overrides(["gas.enabled=false", "feed.mass_flow_kg_h=0", "tube.length=0.035",
                                  *case_overrides])
    sim = Simulation(case)
    sim.add_particles(_lattice(case))
    out = {}
    times = sample_times or [duration]
    for t in times:
        sim.advance(t - 0.01 - sim.time)
        sim.reset_max_overlap()
        sim.advance(0.01)
        out[round(t, 6)] = _bed_quantities(sim)
    return out if sample_times else out[round(duration, 6)]


def _lattice(case) -> np.ndarray:
    """60 grain centres: a square lattice of pitch 1.2 d across the tube and along its first 2 cm,
    each jittered by up to 0.05 d (seeded), none touching."""
    d, R = case["particles.diameter"], case["tube.diameter"] / 2
    rng = np.random.default_rng(0)
    pitch = 1.2 * d
    ys = np.arange(-R + d, R - d + 1e-12, pitch)
    pos = []
    for x in np.arange(d, 0.02, pitch):
        for y in ys:
            for z in ys:
                if math.hypot(y, z) <= R - 0.75 * d:
                    pos.append((x, y, z))
    pos = np.array(pos[:60])
    return pos + rng.uniform(-0.05 * d, 0.05 * d, pos.shape)


def _bed_quantities(sim) -> dict:
    pos = sim.positions
    width = sim.case["output.slice_width"]
    wall = sim.slice_fields(width)["wall_stress"] * math.pi * sim.case["tube.diameter"] * width
    return {"n_particles": int(sim.n_particles),
            "z_mean": float(pos[:, 2].mean()), "z_std": float(pos[:, 2].std()),
            "x_mean": float(pos[:, 0].mean()), "x_std": float(pos[:, 0].std()),
            "wall_force": float(np.nansum(wall)),
            "max_overlap": float(sim.max_overlap / (2 * sim.model.radius)),
            "kinetic_energy": float(sim.kinetic_energy)}


def run_short(orientation: str, duration: float, out: Path, case_overrides=()) -> Path:
    """The default case of `orientation` in the short tube for `duration` s, written to `out`."""
    from engine import Case
    from engine.run import run_case

    case = Case.from_yaml(ROOT / "config" / "cases" / f"{orientation}.yaml",
                          [*(f"{k}={v}" for k, v in SHORT_TUBE.items()), f"run.duration={duration}",
                           *case_overrides])
    return run_case(case, out, quiet=True, overwrite=True)


def run_quantities(ds) -> dict:
    """A short run's key outputs from its case file: the grain books at the end, the mean pressure
    drop, the mean axial grain velocity (volume-weighted over slices and frames), the mean and
    final kinetic energy, and the mean wall stress (volume-weighted like the velocity)."""
    solid = np.nan_to_num(1.0 - ds["porosity"].values.astype(float)[1:])
    weight = solid.sum()

    def weighted(name):
        return float(np.nansum(ds[name].values.astype(float)[1:] * solid) / weight)

    return {"n_particles": int(ds["n_particles"].values[-1]),
            "mass_in": float(ds["mass_in"].values[-1]), "mass_out": float(ds["mass_out"].values[-1]),
            "pressure_drop_mean": float(ds["pressure_drop"].values[1:].mean()),
            "velocity_mean": weighted("velocity"),
            "wall_stress_mean": weighted("wall_stress"),
            "kinetic_energy_mean": float(ds["kinetic_energy"].values[1:].mean()),
            "kinetic_energy_final": float(ds["kinetic_energy"].values[-1])}


def horizontal(duration: float = DURATION["horizontal"], case_overrides=()) -> dict:
    """config/cases/horizontal.yaml (feed 2.49 kg/h, v_s 1 m/s) in a 2.1 cm tube with 6 gas nodes,
    from empty: the first fed grains leave the feed and feel the drag (run_quantities)."""
    return _short("horizontal", duration, case_overrides)


def vertical(duration: float = DURATION["vertical"], case_overrides=()) -> dict:
    """config/cases/vertical.yaml in the same 2.1 cm tube with 6 gas nodes, from empty
    (run_quantities)."""
    return _short("vertical", duration, case_overrides)


_RUNS: dict = {}  # (orientation, duration, overrides) -> case file, for the process's lifetime
_TMP = None


def short_case_file(orientation: str, duration: float, case_overrides=()) -> Path:
    """The case file of run_short, run once per process (the reduction reuses the horizontal run)."""
    global _TMP
    key = (orientation, duration, tuple(case_overrides))
    if key not in _RUNS:
        if _TMP is None:
            _TMP = tempfile.TemporaryDirectory(prefix="plugsim-regression-")
        _RUNS[key] = run_short(orientation, duration, Path(_TMP.name) / f"case{len(_RUNS)}.nc", case_overrides)
    return _RUNS[key]


def _short(orientation, duration, case_overrides) -> dict:
    import xarray as xr

    with xr.open_dataset(short_case_file(orientation, duration, case_overrides)) as ds:
        return run_quantities(ds.load())


def reduction(duration: float = DURATION["horizontal"]) -> dict:
    """The workflow's per-case reduction (rules detect, summary and statistics: analysis.detect,
    analysis.case_summary, analysis.slug_statistics) of (1) the short horizontal run's case file and
    (2) a synthetic case file of tests/analysis/synthetic.py (8 s of 5 cm slugs at 0.3 m/s every
    0.75 s over a noisy pressure drop), whose slugs the engine's short tube cannot form."""
    from analysis import open_case
    from tests.analysis import synthetic

    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        real = short_case_file("horizontal", duration)
        synth = Path(tmp) / "synthetic.nc"
        synthetic.write(synthetic.build(synthetic.periodic(0.75, 0.3, 0.05, 8.0), 8.0), synth)
        for name, path in (("engine", real), ("synthetic", synth)):
            ds = open_case(path)
            out.update({f"{name}.{key}": value for key, value in reduce_case(ds).items()})
            ds.close()
    return out


def reduce_case(ds) -> dict:
    """detect -> case_summary -> slug_statistics on one case file, as the workflow's rules run them."""
    from analysis import case_summary, detect, slug_statistics

    out = {}
    slugs = detect(ds)
    summary = case_summary(ds, slugs=slugs)
    out["slug_rows"] = int(len(slugs))
    out["slug_ids"] = int(slugs["slug_id"].nunique()) if len(slugs) else 0
    for key in ("pressure_drop", "pressure_drop_sem", "t_start", "dense_fraction", "slug_fraction",
                "slug_rate", "slug_velocity", "max_velocity", "slug_length", "slug_length_total",
                "n_particles", "mass_flow_in", "mass_flow_out"):
        out[key] = _number(summary[key])
    out["regime"] = str(summary["regime"])
    if len(slugs):
        stats = slug_statistics(slugs, t_start=summary["t_start"])
        out["stats_passages"] = int(stats["n_slugs"].sum())
        out["stats_rate_mean"] = _number(stats["rate"].mean())
        out["stats_length_mean"] = _number(np.nanmean(stats["length_mean"]))
        out["stats_velocity_mean"] = _number(np.nanmean(stats["slug_velocity_mean"]))
    return out


def kernel_cache_dir() -> Path:
    """A numba cache folder for the current numba source of the engine (engine/kernels/*.py,
    engine/gas.py, engine/gas_grid.py and the kernels' parameter declaration
    engine/parameters.py), in the temporary folder: a new source compiles afresh (about 45 s of
    CPU), an unchanged one reuses it."""
    digest = hashlib.sha256()
    engine = ROOT / "engine"
    sources = [engine / name for name in ("gas.py", "gas_grid.py", "parameters.py")]
    for path in sorted((engine / "kernels").glob("*.py")) + sources:
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    import numba
    digest.update(numba.__version__.encode())
    return Path(tempfile.gettempdir()) / f"plugsim-regression-numba-{digest.hexdigest()[:16]}"


def run_in_child(names, cpu=None) -> dict:
    """{case: quantities} of `names`, computed by a child process with kernel_cache_dir(); `cpu`:
    (name, LLVM feature string) to compile the kernels for instead of this machine's own."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(kernel_cache_dir()),
               PYTHONPATH=os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    if cpu is not None:  # with a cache of its own: no two compiles into one folder at once
        digest = hashlib.sha256("\0".join(cpu).encode()).hexdigest()[:8]
        env.update(NUMBA_CACHE_DIR=f"{env['NUMBA_CACHE_DIR']}-{digest}", NUMBA_CPU_NAME=cpu[0],
                   NUMBA_CPU_FEATURES=cpu[1])
    with tempfile.TemporaryDirectory(prefix="plugsim-regression-") as tmp:
        out = Path(tmp) / "values.json"
        res = subprocess.run([sys.executable, "-m", "tests.regression.cases", str(out), *names], cwd=ROOT,
                             env=env, capture_output=True, text=True)
        if res.returncode != 0:
            raise RuntimeError(f"the regression cases failed in the child process:\n{res.stderr[-4000:]}")
        return json.loads(out.read_text())


def host_cpu(wide_vectors: bool) -> tuple[str, str]:
    """(name, LLVM feature string) of this machine's CPU with the compiler told to prefer its
    widest vectors (`wide_vectors`) or half as wide ones: 512 against 256 bits where the CPU has
    AVX-512, 256 against 128 bits otherwise. Both run here; LLVM picks its loops' vector width (and
    with it the order of any sum it may reassociate) from this preference."""
    import llvmlite.binding as ll

    features = ll.get_host_cpu_features()
    preference = "prefer-256-bit" if features.get("avx512f") else "prefer-128-bit"
    return ll.get_host_cpu_name(), f"{features.flatten()},{'-' if wide_vectors else '+'}{preference}"


def _number(value):
    value = float(value)
    return None if math.isnan(value) else value


# ---- tolerances ---------------------------------------------------------------------------------
# (rel, abs): a value passes when |value - baseline| <= abs + rel |baseline|. Measured gaps (relative,
# python -m tests.regression.gaps, at the durations above and 10 ms apart around them):
#   rounding:  a run whose kernels were compiled in-process (fresh NUMBA_CACHE_DIR) against one that
#              loaded them from the cache: bit-identical (0) at every frame to 0.15 s in every case
#              (the kernels' fastmath has no `reassoc`, so no sum is reordered by the compiler);
#              also the same bits with the kernels compiled for other vector widths
#              (test_the_cases_do_not_depend_on_the_vector_width_the_kernels_are_compiled_for).
#   physics:   a 1 % change of one force-law line each: k_n in laws.normal_force
#              (1.01 * c[1] * delta), the Coulomb cap fc of laws.slip_force (1.01 * mu * fn), the
#              drag in gas.drag_forces (s = -1.01 * vp / ...), run with kernels compiled from the
#              changed source.
EXACT = (0.0, 0.0)
MASS = (1e-12, 0.0)  # grain counts times the grain mass: exact up to the summation's rounding
TOLERANCES = {
    # packed_bed at 0.15 s. rounding: 0. physics at 0.15 s: k_n z_mean 1.4e-2, x_mean 9.8e-3, z_std
    # 1.3e-2, x_std 3.8e-3, wall_force 2.8e-2, kinetic_energy 0.11; friction z_mean 5.1e-3, x_mean 2.8e-3, z_std 1.7e-2, x_std 4.8e-3, wall_force 0.26,
    # kinetic_energy 4.0e-3; drag 0 (gas off: the drag is the runs' to catch). A change of the
    # last bits of every viscous tangential force (its branch chosen on squares) moved x_mean by
    # 4.5e-3, z_std 7.6e-3, kinetic_energy 6.7e-2 and max_overlap 0.22 by 0.15 s: the settling
    # pile amplifies rounding at every step to the size of the 1 % physics gaps, so a failure
    # here says that the arithmetic changed, not how much the physics did. 1e-6 is 2800 times
    # below the smallest physics gap of the positions. Wall force, overlap and kinetic energy
    # hang on single contacts (their physics gaps jump between 6e-3 and 0.8 from frame to
    # frame), so they get 1e-3.
    "packed_bed": {"*": (1e-6, 0.0), "n_particles": EXACT, "wall_force": (1e-3, 0.0),
                   "max_overlap": (1e-3, 0.0), "kinetic_energy": (1e-3, 0.0)},
    # horizontal at 0.08 s, the default split gas scheme. rounding: 0. physics at 0.08 s:
    # pressure_drop_mean k_n 3.0e-4, friction 3.7e-5, drag 7.7e-4; velocity_mean 1.1e-3, 5.2e-4,
    # 4.5e-3; kinetic_energy_mean 2.4e-3, 1.0e-2, 1.2e-2; kinetic_energy_final 4.3e-3, 1.0e-2,
    # 1.4e-2; wall_stress_mean 0.33, 0.58, 0.26. So 1e-5: 3.7 times below the smallest physics gap
    # (friction on the pressure drop; its velocity gap is 52 times the tolerance); the wall stress
    # 1e-3 (260 times below its physics gaps). Grain books: the feed is kinematic, no grain has
    # left yet.
    "horizontal": {"*": (1e-5, 0.0), "n_particles": EXACT, "mass_in": MASS, "mass_out": MASS,
                   "wall_stress_mean": (1e-3, 0.0)},
    # vertical at 0.08 s, the default split gas scheme. rounding: 0. physics at 0.08 s:
    # pressure_drop_mean k_n 8.2e-5, friction 3.3e-4, drag 6.7e-4; velocity_mean 5.2e-3, 1.4e-2, 4.9e-3;
    # kinetic_energy_mean 1.2e-2, 2.0e-2, 1.3e-2; kinetic_energy_final 2.3e-3, 5.9e-2, 0.12.
    # 1e-5 is 8 times below the smallest (k_n on the pressure drop; its velocity gap is 520 times
    # the tolerance). No grain touches the wall yet at 0.08 s: wall_stress_mean is 0 (abs 1e-9 Pa)
    # and turns to order 1 Pa when one does (with the drag 1 % stronger one does by 0.08 s).
    "vertical": {"*": (1e-5, 0.0), "n_particles": EXACT, "mass_in": MASS, "mass_out": MASS,
                 "wall_stress_mean": (1e-3, 1e-9)},
    # reduction. engine.*: the summary of the horizontal case file (0.08 s, no slug yet): its
    # pressure drop, dense and slug fractions and mean grain count are averages of the run's
    # frames, so the horizontal tolerance 1e-5 (float32 slice fields: a rounding-level change of
    # the run either leaves them bit-identical or moves them by a float32 ulp, 6e-8). rounding: 0;
    # physics at 0.08 s: k_n 3.7e-4, friction 4.5e-5, drag 9.3e-4. The window
    # start is a frame time (exact), counts and the regime exact. synthetic.*: detect,
    # case_summary and slug_statistics on a synthetic case file from numpy's seeded generator:
    # deterministic arithmetic, so 1e-9 (a numpy or pandas change of summation order moves it by
    # 1e-15 or so) catches any change of the analysis.
    "reduction": {"engine.*": (1e-5, 1e-12), "synthetic.*": (1e-9, 1e-12)},
}
COUNTS = ("n_particles", "slug_rows", "slug_ids", "stats_passages", "t_start", "regime")


def tolerance(case: str, quantity: str) -> tuple[float, float]:
    """(rel, abs) of `quantity` in `case`: its own entry, else exact for counts, else the default
    of its prefix (`engine.*`) or of the case (`*`)."""
    table = TOLERANCES[case]
    if quantity in table:
        return table[quantity]
    prefix, _, short = quantity.rpartition(".")
    if short in COUNTS:
        return EXACT
    return table.get(f"{prefix}.*" if prefix else "*", table.get("*", EXACT))


CASES = {"packed_bed": packed_bed, "horizontal": horizontal, "vertical": vertical, "reduction": reduction}


if __name__ == "__main__":
    import warnings

    warnings.simplefilter("ignore")  # a run's warnings go to stderr, not into the values
    target, names = Path(sys.argv[1]), sys.argv[2:] or list(CASES)
    # the runs through run_case first: the first of them compiles or loads the kernels (under
    # run_case's compile lock where the engine has one), packed_bed then finds them loaded
    order = sorted(names, key=lambda name: name == "packed_bed")
    values = {name: CASES[name]() for name in order}
    target.write_text(json.dumps({name: values[name] for name in names}, indent=1) + "\n")
