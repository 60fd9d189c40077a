"""Every command of README.md works as written: the workflow commands as dry runs (`-n`), the
others run on short cases, from a scratch copy of config/ and resources/ (results go there).

The commands are extracted from the README (bash blocks, split at `&&`, and inline code that starts
with a program); each must have an entry in HOW, so a command added to the README without a way
to exercise it fails here.
"""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PROGRAMS = ("plugsim", "snakemake", "python", "python3", "pip", "pytest", ".")

# command -> how it is exercised: "dry" (snakemake -n), "run" (as written, with the extra arguments
# that shorten it), or "other" (checked by a function below, or the reason it is not run here)
HOW = {
    "python3 -m venv .venv": ("other", "set-up: the tests run in the environment it makes"),
    ". .venv/bin/activate": ("other", "set-up: the tests run in the environment it makes"),
    'pip install -c requirements.lock -e ".[workflow,test]"': ("other", "extras"),
    'pip install -c requirements.lock -e ".[test]"': ("other", "extras"),
    "pip freeze --exclude-editable": ("other", "regenerates the lock file"),
    'pip install -e ".[slurm]"': ("other", "extras"),
    "pytest": ("other", "the test suite itself"),
    "snakemake -j2": ("dry", "results/validation/validation.csv"),
    "snakemake --report report.html": ("other", "report"),
    "snakemake -j2 results/curves/h_restitution.png --configfile my.yaml":
        ("dry", "results/cases/h_restitution/particles.restitution~0.9.nc"),
    "snakemake -j1 validation reference --configfile config/partial.yaml": ("dry", "docs/reference/paper"),
    "snakemake --workflow-profile workflow/profiles/slurm": ("dry", "results/validation/validation.csv"),
    "plugsim run config/cases/horizontal.yaml --out results/h.nc --set run.duration=5 --set particles.friction=0.1":
        ("run", ["--set", "run.duration=0.05"]),  # the later --set wins: 5 frames instead of 500
    "plugsim --version": ("run", []),
    "plugsim keys": ("run", []),
    "plugsim check config/cases/horizontal.yaml --set particles.friction=0.1": ("run", []),
    "plugsim bench": ("run", ["--steps", "20", "--repeats", "1", "--no-compile"]),
    "python benchmarks/lammps/compare.py": ("other", "lammps"),
    "plugsim run config/cases/horizontal.yaml --out h.nc --set run.duration=4 --set output.tube_snapshot_interval=0.05":
        ("run", ["--set", "run.duration=0.1"]),
    # need a case file with whole-tube snapshots: tests/engine/test_export.py runs both on one
    "plugsim export results/h.nc --out results/h_vtk    # ParaView: open grains.pvd and slices.pvd":
        ("other", "tests/engine/test_export.py"),
    "plugsim animate results/h.nc --out results/h.gif   # or .mp4 (needs ffmpeg), or .png: the last frame":
        ("other", "tests/engine/test_export.py"),
    "plugsim animate h.nc --out docs/img/grains.png": ("other", "tests/engine/test_export.py"),
}


def readme_commands() -> list[str]:
    """The README's shell commands, in order, without repeats."""
    text = README.read_text()
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.strip().splitlines():
            commands += [part.strip() for part in line.split("&&")]
    prose = re.sub(r"```.*?```", "", text, flags=re.S)
    for span in re.findall(r"`([^`]+)`", prose):
        span = " ".join(span.split())
        if span.split()[0] in PROGRAMS:
            commands.append(span)
    return list(dict.fromkeys(commands))


def readme_block(language: str) -> str:
    blocks = re.findall(rf"```{language}\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) == 1, f"expected one {language} block in README.md"
    return re.sub(r"^  ", "", blocks[0], flags=re.M)  # the YAML block is indented in a list item


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    """A fresh-clone-like working directory: config/, resources/, the SLURM profile, results/, and
    the README's sweep file my.yaml."""
    work = tmp_path_factory.mktemp("readme")
    for name in ("config", "resources", "workflow/profiles"):
        shutil.copytree(ROOT / name, work / name)
    (work / "results").mkdir()
    (work / "my.yaml").write_text(readme_block("yaml"))
    return work


def run(argv: list[str], cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(argv, cwd=cwd, capture_output=True, text=True, timeout=timeout)


def test_every_readme_command_has_a_way_to_be_exercised():
    assert set(readme_commands()) == set(HOW)


@pytest.mark.parametrize("command", [c for c, (how, _) in HOW.items() if how == "dry"])
def test_workflow_command_dry_runs(work, command):
    expected = HOW[command][1]
    words = shlex.split(command)
    res = run([sys.executable, "-m", "snakemake", "--snakefile", str(ROOT / "Snakefile"), *words[1:], "-n"], work)
    assert res.returncode == 0, res.stderr[-3000:]
    assert expected in res.stdout + res.stderr


@pytest.mark.parametrize("command", [c for c, (how, _) in HOW.items() if how == "run"])
def test_plugsim_command_runs(work, command):
    words = shlex.split(command)
    res = run([sys.executable, "-m", "engine.cli", *words[1:], *HOW[command][1]], work)
    assert res.returncode == 0, res.stderr[-3000:]
    if words[1] == "run":
        import xarray as xr
        with xr.open_dataset(work / "results/h.nc") as ds:
            assert ds.sizes["time"] == 6 and "friction: 0.1" in ds.attrs["config_yaml"]
    elif words[1] == "--version":
        import engine
        assert res.stdout == f"plugsim {engine.__version__}\n"
    elif words[1] == "check":
        assert "valid" in res.stdout and "time step" in res.stdout
    elif words[1] == "bench":
        assert "particle-steps per s" in res.stdout
    else:
        assert "particles.friction" in res.stdout


def test_python_example_runs(work):
    res = run([sys.executable, "-c", readme_block("python")], work)
    assert res.returncode == 0, res.stderr[-3000:]
    time_, grains, pressure_drop, shape = res.stdout.split(" ", 3)
    assert float(time_) == 0.5 and int(grains) > 0 and shape.strip() == f"({grains}, 3)"


def test_install_extras_exist():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    for command in HOW:
        if command.startswith("pip install") and "-e" in command:
            named = re.search(r"\[(.*)\]", command).group(1).split(",")
            assert set(named) <= set(extras), command


def test_slurm_plugin_named_in_the_readme_is_the_profiles_executor():
    profile = yaml.safe_load((ROOT / "workflow/profiles/slurm/config.yaml").read_text())
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert 'pip install -e ".[slurm]"' in HOW
    assert any(dep.startswith(f"snakemake-executor-plugin-{profile['executor']}") for dep in extras["slurm"])


def test_report_command_is_run_by_the_workflow_test():
    """`snakemake --report report.html` needs a finished run: the reduced workflow's test makes one
    (marker `workflow`) and then runs this command."""
    source = (ROOT / "tests/workflow/test_workflow.py").read_text()
    assert 'snakemake("--report", "report.html"' in source


def test_lammps_comparison_runs_or_says_lammps_is_missing(work):
    res = run([sys.executable, str(ROOT / "benchmarks/lammps/compare.py"), "--repeats", "1", "--steps", "20"], work)
    if res.returncode == 2:  # no LAMMPS on this machine: the command says so in one line
        assert res.stderr.strip().splitlines() == [res.stderr.strip()] and "LAMMPS not found" in res.stderr
    else:
        assert res.returncode == 0, res.stderr[-3000:]


def test_lock_file_pins_every_dependency_the_commands_install():
    """`pip install -c requirements.lock -e ".[...]"` installs exact versions only if the lock names
    every dependency of the project and of the extras the README installs."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    wanted = list(project["dependencies"])
    for extra in ("workflow", "test", "slurm"):
        wanted += project["optional-dependencies"][extra]
    pinned = {line.split("==")[0].lower().replace("_", "-")
              for line in (ROOT / "requirements.lock").read_text().splitlines()
              if "==" in line and not line.startswith("#")}
    for requirement in wanted:
        name = re.split(r"[<>=!~\[ ;]", requirement, maxsplit=1)[0].lower().replace("_", "-")
        assert name in pinned, f"{name} is not pinned in requirements.lock"
