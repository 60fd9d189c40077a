"""Every command of README.md works as written, typed top to bottom: the workflow commands as dry
runs (`-n`), the others run on short cases one after the other in the README's order, from a
scratch copy of config/ and resources/ (results go there). No command writes into a file the
repository tracks unless the README says it does, and the job and case counts the README quotes
are those of the dry runs it names.

The commands are extracted from the README in the order they appear (bash blocks, split at `&&`,
and inline code that starts with a program); each must have an entry in HOW, so a command added to
the README without a way to exercise it fails here.
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
    'pytest -m "not slurm"': ("other", "the test suite itself, without the SLURM test"),
    "snakemake -j2": ("dry", "results/validation/validation.csv"),
    "snakemake --report report.html": ("other", "report"),
    "snakemake --report report.html --configfile config/ci.yaml": ("other", "report"),
    "snakemake -n --configfile config/ci.yaml": ("other", "test_quoted_counts_are_the_dry_runs"),
    "snakemake -n": ("other", "test_quoted_counts_are_the_dry_runs"),
    "snakemake -j2 results/curves/h_restitution.png --configfile my.yaml":
        ("dry", "results/cases/h_restitution/particles.restitution~0.9.nc"),
    "snakemake -j1 validation reference --configfile config/partial.yaml": ("dry", "docs/reference/paper"),
    "snakemake --workflow-profile workflow/profiles/slurm": ("dry", "results/validation/validation.csv"),
    "snakemake -j2 calibration --configfile config/calibration.yaml":
        ("dry", "results/calibration/vertical_B/cases/B/gas.viscosity~6.5e-05_particles.friction~0.5.nc"),
    "plugsim run config/cases/horizontal.yaml --out results/h.nc --set run.duration=5 --set particles.friction=0.1":
        ("run", ["--set", "run.duration=0.05"]),  # the later --set wins: 5 frames instead of 500
    "plugsim --version": ("run", []),
    "plugsim keys": ("run", []),
    "plugsim check config/cases/horizontal.yaml --set particles.friction=0.1": ("run", []),
    "plugsim bench": ("run", ["--steps", "20", "--repeats", "1", "--no-compile"]),
    "python benchmarks/lammps/compare.py": ("other", "lammps"),
    "plugsim run config/cases/horizontal.yaml --out results/grains.nc --set run.duration=4 --set output.tube_snapshot_interval=0.05":
        ("run", ["--set", "run.duration=0.1"]),  # snapshots at 0, 0.05 and 0.1 s
    # read the case file with whole-tube snapshots that the command before them wrote
    "plugsim export results/grains.nc --out results/grains_vtk    # ParaView: open grains.pvd and slices.pvd":
        ("run", []),
    "plugsim animate results/grains.nc --out results/grains.gif   # or .mp4 (needs ffmpeg)": ("run", []),
    "plugsim animate results/grains.nc --out results/img/grains.png   # .png: the last frame": ("run", []),
}

# commands that write into files the repository tracks, on purpose: what they write (the README
# must say so within the sentence that gives the command)
WRITES_TRACKED = {
    "snakemake -j1 validation reference --configfile config/partial.yaml": "docs/reference/paper/",
}


def readme_commands() -> list[str]:
    """The README's shell commands in the order they appear (top to bottom), without repeats."""
    text = README.read_text()
    commands = []
    for block in re.finditer(r"```(\w*)\n(.*?)```|`([^`]+)`", text, flags=re.S):
        language, body, span = block.groups()
        if language == "bash":
            for line in body.strip().splitlines():
                commands += [part.strip() for part in line.split("&&")]
        elif span is not None:
            span = " ".join(span.split())
            if span.split()[0] in PROGRAMS:
                commands.append(span)
    return list(dict.fromkeys(commands))


def written_paths(command: str) -> list[str]:
    """The paths a command names as its output (`--out`, `--report`)."""
    words = shlex.split(command, comments=True)
    return [words[i + 1] for i, word in enumerate(words[:-1]) if word in ("--out", "--report")]


def tracked(paths: list[str]) -> list[str]:
    """Those of paths (files or folders, relative to the repository) that git tracks."""
    if not paths:
        return []
    if subprocess.run(["git", "rev-parse"], cwd=ROOT, capture_output=True).returncode != 0:
        pytest.skip("not a git checkout")
    listed = subprocess.run(["git", "ls-files", "--", *paths], cwd=ROOT, capture_output=True, text=True,
                            check=True).stdout.splitlines()
    return [p for p in paths if any(f == p or f.startswith(p.rstrip("/") + "/") for f in listed)]


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


def dry_run(work: Path, words: list[str]) -> subprocess.CompletedProcess:
    return run([sys.executable, "-m", "snakemake", "--snakefile", str(ROOT / "Snakefile"), *words, "-n"], work)


@pytest.mark.parametrize("command", [c for c, (how, _) in HOW.items() if how == "dry"])
def test_workflow_command_dry_runs(work, command):
    expected = HOW[command][1]
    res = dry_run(work, shlex.split(command)[1:])
    assert res.returncode == 0, res.stderr[-3000:]
    assert expected in res.stdout + res.stderr
    # what its jobs would write: nothing the repository tracks, unless the README says so
    outputs = [p.strip() for line in re.findall(r"^\s*output: (.*)$", res.stdout, flags=re.M)
               for p in line.split(",")]
    assert outputs
    assert set(tracked(outputs)) <= {WRITES_TRACKED.get(command, "").rstrip("/")}, command


def test_readme_commands_run_in_the_order_written(work):
    """The commands that simulate, export and animate, run one after the other as the README lists
    them (shortened by HOW's extra arguments): each works on what the commands above it made."""
    import xarray as xr
    import engine
    for command in [c for c in readme_commands() if HOW[c][0] == "run"]:
        words = shlex.split(command, comments=True)
        res = run([sys.executable, "-m", "engine.cli", *words[1:], *HOW[command][1]], work)
        assert res.returncode == 0, f"{command}\n{res.stderr[-3000:]}"
        out = work / written_paths(command)[0] if written_paths(command) else None
        if words[1] == "run":
            with xr.open_dataset(out) as ds:
                assert ds.sizes["time"] >= 6 and ds.attrs["stop_reason"] == "duration"
                if "particles.friction=0.1" in words:
                    assert "friction: 0.1" in ds.attrs["config_yaml"]
                if "output.tube_snapshot_interval=0.05" in words:
                    assert ds.sizes["tube_snapshot_time"] == 3 and ds.tube_snapshot_count.values[-1] > 0
        elif words[1] == "export":
            assert {"grains.pvd", "slices.pvd", "README.txt"} <= {p.name for p in out.iterdir()}
            assert list(out.glob("grains_*.vtu")) and list(out.glob("slices_*.vtu"))
        elif words[1] == "animate":
            assert out.stat().st_size > 0
        elif words[1] == "--version":
            assert res.stdout == f"plugsim {engine.__version__}\n"
        elif words[1] == "check":
            assert "valid" in res.stdout and "time step" in res.stdout
        elif words[1] == "bench":
            assert "particle-steps per s" in res.stdout
        else:
            assert "particles.friction" in res.stdout


def test_export_and_animate_read_a_case_file_with_snapshots_made_above_them():
    """Typed top to bottom, `plugsim export`/`animate` get a case file that a `plugsim run` above
    them wrote with whole-tube snapshots (output.tube_snapshot_interval)."""
    with_snapshots = {}  # case file -> whether the latest run writing it records snapshots
    readers = 0
    for command in readme_commands():
        words = shlex.split(command, comments=True)
        if words[:2] == ["plugsim", "run"]:
            with_snapshots[written_paths(command)[0]] = any(
                w.startswith("output.tube_snapshot_interval=") for w in words)
        elif words[:1] == ["plugsim"] and words[1] in ("export", "animate"):
            readers += 1
            assert with_snapshots.get(words[2]), \
                f"{command!r}: no README command above it writes {words[2]} with whole-tube snapshots"
    assert readers


def test_no_readme_command_writes_into_a_tracked_file():
    """`--out`/`--report` of every command lie outside what git tracks (under results/ for
    plugsim's), so typing the README does not overwrite committed files; the workflow commands'
    outputs are checked in test_workflow_command_dry_runs."""
    for command in readme_commands():
        paths = written_paths(command)
        assert not tracked(paths), f"{command!r} writes into tracked {tracked(paths)}"
        if command.startswith("plugsim"):
            assert all(p.startswith("results/") for p in paths), f"{command!r}: outputs go to results/"
    text = " ".join(README.read_text().split())
    for command, path in WRITES_TRACKED.items():
        assert command in readme_commands()
        sentence = text[text.index(" ".join(command.split())):]
        sentence = sentence[:sentence.find(". ") if ". " in sentence else len(sentence)]
        assert path in sentence, f"the README does not say that {command!r} writes {path}"


def job_stats(output: str) -> dict[str, int]:
    table = output[output.index("Job stats:"):].split("\n\n")[0]
    return {name: int(count) for name, count in re.findall(r"^(\w+)\s+(\d+)$", table, flags=re.M)}


def test_quoted_counts_are_the_dry_runs(work):
    """The cases and jobs the README quotes for the CI and the paper configuration are the
    `simulate` and `total` lines of the dry runs it names."""
    text = " ".join(README.read_text().split())
    quoted = re.search(r"CI configuration \(`--configfile config/ci.yaml`\) has (\d+) cases .*? and "
                       r"(\d+) jobs; the paper configuration has (\d+) cases .*? and (\d+) jobs \(the "
                       r"`total` and `simulate` lines of `snakemake -n --configfile config/ci.yaml` and "
                       r"of `snakemake -n`\)", text)
    assert quoted, "the README quotes the configurations' cases and jobs with the dry runs that count them"
    for configfile, (cases, jobs) in ((["--configfile", "config/ci.yaml"], quoted.group(1, 2)),
                                      ([], quoted.group(3, 4))):
        res = dry_run(work, configfile)
        assert res.returncode == 0, res.stderr[-3000:]
        stats = job_stats(res.stdout)
        assert (stats["simulate"], stats["total"]) == (int(cases), int(jobs)), configfile


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
