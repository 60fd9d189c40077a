"""The SLURM profile on a real cluster: a private single-node SLURM (munged, slurmctld, slurmd from
Debian's packages, started by tests/workflow/slurm_setup.sh in a temporary directory) runs a two-case
reduced workflow submitted through `--workflow-profile workflow/profiles/slurm` by snakemake's SLURM
executor plugin.

Marker `slurm`, part of the default test run. Where the cluster cannot be had (not root, no apt-get,
the plugin not installed) the tests skip with the reason, except in CI (CI=true), where they fail.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
SETUP = ROOT / "tests/workflow/slurm_setup.sh"
PROFILE = ROOT / "workflow/profiles/slurm"
MISSING = 77  # slurm_setup.sh: a prerequisite is missing
RESTITUTIONS = [0.3, 0.9]

pytestmark = pytest.mark.slurm


def unavailable(reason: str, ci: bool) -> None:
    """Skip for want of `reason`, or fail in CI, where the SLURM run must happen."""
    if ci:
        pytest.fail(f"{reason} (CI=true: the SLURM test must run)", pytrace=False)
    pytest.skip(reason)


def free_ports(count: int) -> list[int]:
    """Ports on the loopback interface that no one listens on now."""
    sockets = [socket.socket() for _ in range(count)]
    try:
        for s in sockets:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def daemons_alive(directory: Path) -> list[str]:
    """Pid files in `directory` whose daemon still runs."""
    alive = []
    for name in ("slurmctld.pid", "slurmd.pid", "munge/munged.pid"):
        pidfile = directory / name
        if pidfile.exists() and pidfile.read_text().strip():
            try:
                os.kill(int(pidfile.read_text()), 0)
                alive.append(pidfile.name)
            except ProcessLookupError:
                pass
    return alive


@pytest.fixture(scope="module")
def slurm(tmp_path_factory):
    """Environment (SLURM_CONF, ports) of a running single-node cluster; stopped afterwards."""
    ci = os.environ.get("CI") == "true"
    if importlib.util.find_spec("snakemake_executor_plugin_slurm") is None:
        unavailable("snakemake-executor-plugin-slurm is not installed (pip install -e '.[test]')", ci)
    directory = tmp_path_factory.mktemp("slurm")
    ctld_port, slurmd_port = free_ports(2)
    env = {k: v for k, v in os.environ.items() if not k.startswith("SLURM")}  # not an outer job's
    env |= {"SLURM_CONF": str(directory / "slurm.conf"),
            "SLURMCTLD_PORT": str(ctld_port), "SLURMD_PORT": str(slurmd_port)}
    try:
        # the packages' install took 10 s here; the limit leaves room for a slow mirror
        start = subprocess.run(["bash", str(SETUP), "start", str(directory)], env=env,
                               capture_output=True, text=True, timeout=900)
        if start.returncode == MISSING:
            unavailable(start.stderr.strip().splitlines()[-1], ci)
        assert start.returncode == 0, start.stderr[-3000:]
        yield {"env": env, "directory": directory}
    finally:
        subprocess.run(["bash", str(SETUP), "stop", str(directory)], env=env, capture_output=True,
                       timeout=120)
        assert not daemons_alive(directory), "the SLURM daemons outlived the teardown"


def scratch(tmp_path: Path) -> Path:
    """A working directory with copies of config/ and resources/ and the two-case sweep."""
    for name in ("config", "resources"):
        shutil.copytree(ROOT / name, tmp_path / name)
    (tmp_path / "config/slurm.yaml").write_text(yaml.safe_dump({"sweeps": {"slurm_pair": {
        "base": "config/cases/horizontal.yaml",
        "overrides": {"tube.length": 0.03, "gas.nodes_x": 9, "run.duration": 1.0},
        "position": 0.015,
        "parameters": {"particles.restitution": RESTITUTIONS},
        "same_as": {"wall.restitution": "particles.restitution"}}}}))
    return tmp_path


def squeue_records(env: dict, run_id: str) -> dict[str, dict]:
    """SLURM's own records of the jobs named `run_id` (finished ones too, for MinJobAge)."""
    out = subprocess.run(["squeue", "--states=all", "--noheader", "--name", run_id,
                          "--format=%i|%T|%N|%k"], env=env, capture_output=True, text=True,
                         timeout=60, check=True).stdout
    records = {}
    for line in out.splitlines():
        job_id, state, node, comment = line.strip().split("|", 3)
        records[job_id] = {"state": state, "node": node, "comment": comment}
    return records


def test_unavailable_skips_outside_ci_and_fails_in_ci():
    with pytest.raises(pytest.skip.Exception, match="no apt-get"):
        unavailable("no apt-get", ci=False)
    with pytest.raises(pytest.fail.Exception, match="CI=true"):
        unavailable("no apt-get", ci=True)


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("setpriv") is None,
                    reason="needs root and setpriv to run the script as another user")
def test_setup_reports_a_missing_prerequisite_with_its_own_exit_code(tmp_path):
    """Not root: exit 77 (the fixture's skip, or failure in CI) and one line saying why."""
    with SETUP.open() as script:  # read as root: the checkout may be closed to other users
        run = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups",
                              "bash", "-s", "start", str(tmp_path / "cluster")],
                             stdin=script, cwd="/", capture_output=True, text=True, timeout=60)
    assert run.returncode == MISSING, run.stderr
    assert run.stderr.strip() == "slurm_setup: must run as root to start slurmd and munged"


@pytest.mark.parametrize("variable, value, allowed", [
    ("SLURMCTLD_PORT", "abc", "[1024, 65535]"),
    ("SLURMD_PORT", "80", "[1024, 65535]"),
    ("SLURM_START_TIMEOUT_S", "0", "[1, 3600]"),
])
def test_setup_refuses_a_bad_setting_before_any_work(tmp_path, variable, value, allowed):
    run = subprocess.run(["bash", str(SETUP), "start", str(tmp_path / "cluster")],
                         env={**os.environ, variable: value}, capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert run.stderr.strip() == f"slurm_setup: {variable} = '{value}' must be an integer in {allowed}"
    assert not (tmp_path / "cluster").exists()


def test_profile_documents_valid_keys_for_a_cluster_without_accounting(tmp_path):
    """The profile's commented-out keys for a cluster without accounts or accounting database are
    settings the plugin accepts (a wrong value of the same key is refused: the dry run checks)."""
    if importlib.util.find_spec("snakemake_executor_plugin_slurm") is None:
        unavailable("snakemake-executor-plugin-slurm is not installed (pip install -e '.[test]')",
                    os.environ.get("CI") == "true")
    text = (PROFILE / "config.yaml").read_text()
    keys = ["slurm-no-account: true", "slurm-status-command: squeue"]
    for key in keys:
        assert f"# {key}" in text
        text = text.replace(f"# {key}", key)
    for status, expected in (("squeue", 0), ("nosuch", 1)):
        profile = tmp_path / status
        profile.mkdir()
        (profile / "config.yaml").write_text(text.replace("command: squeue", f"command: {status}"))
        run = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--snakefile",
                              str(ROOT / "Snakefile"), "--workflow-profile", str(profile),
                              "--configfile", "config/ci.yaml"],
                             cwd=ROOT, capture_output=True, text=True, timeout=300)
        assert run.returncode == expected, run.stderr[-3000:]
    assert "Invalid status command" in run.stderr


def test_setup_is_idempotent(slurm):
    """A second start finds the daemons running and the node idle, and starts nothing new."""
    directory = slurm["directory"]
    pids = {p: (directory / p).read_text() for p in ("slurmctld.pid", "slurmd.pid", "munge/munged.pid")}
    again = subprocess.run(["bash", str(SETUP), "start", str(directory)], env=slurm["env"],
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 0, again.stderr
    assert {p: (directory / p).read_text() for p in pids} == pids


def test_two_cases_run_as_slurm_jobs_through_the_profile(slurm, tmp_path):
    work = scratch(tmp_path)
    targets = ["results/curves/slurm_pair.csv", "results/curves/slurm_pair.png"]
    cmd = [sys.executable, "-m", "snakemake", "--snakefile", str(ROOT / "Snakefile"),
           "--workflow-profile", str(PROFILE), "--configfile", "config/slurm.yaml",
           # what this cluster lacks: accounts and the accounting database sacct would read
           "--slurm-no-account", "--slurm-status-command", "squeue",
           # short jobs: poll early (the interval then grows by 10 s while no job finishes)
           "--slurm-init-seconds-before-status-checks", "2",
           "--slurm-keep-successful-logs", "--latency-wait", "5", "--", *targets]
    start = time.monotonic()
    run = subprocess.run(cmd, cwd=work, env=slurm["env"], capture_output=True, text=True, timeout=600)
    wall = time.monotonic() - start
    print(f"SLURM workflow: {wall:.0f} s wall")
    log = run.stdout + run.stderr
    assert run.returncode == 0, log[-5000:]

    import pandas as pd
    import xarray as xr
    from matplotlib.image import imread

    cases = {e: work / f"results/cases/slurm_pair/particles.restitution~{e}.nc" for e in RESTITUTIONS}
    for restitution, path in cases.items():
        with xr.open_dataset(path) as ds:
            # a sweep case runs until steady, at most run.duration
            assert ds.attrs["stop_reason"] in {"steady", "max_duration"}
            t_end = float(ds["time"].max())
            assert 0 < t_end <= 1.0 + 1e-9  # 1e-9 s: the float sum of the time steps
            if ds.attrs["stop_reason"] == "max_duration":
                assert t_end == pytest.approx(1.0)
            assert (ds["n_particles"] > 0).any()
            assert f"restitution: {restitution}" in ds.attrs["config_yaml"]
    table = pd.read_csv(work / "results/curves/slurm_pair.csv", comment="#")
    assert sorted(table["particles.restitution"]) == RESTITUTIONS
    assert (table["pressure_drop"] > 0).all()
    assert imread(work / "results/curves/slurm_pair.png").ndim == 3

    # each case was a SLURM job: snakemake's submissions, SLURM's own records and the job logs agree
    run_id = re.search(r"SLURM run ID: (\S+)", log).group(1)
    submitted = dict(re.findall(r"submitted with SLURM jobid (\d+) \(log: ([^)]*)\)", log))
    simulate = {job_id: Path(path) for job_id, path in submitted.items() if "/rule_simulate/" in path}
    assert len(simulate) == len(RESTITUTIONS), log[-5000:]
    records = squeue_records(slurm["env"], run_id)
    assert set(submitted) <= set(records), records  # every submission is one of this run's jobs
    host = socket.gethostname().split(".")[0]
    for job_id, job_log in simulate.items():
        assert records[job_id]["state"] == "COMPLETED", records[job_id]
        assert records[job_id]["node"] == host
        assert records[job_id]["comment"].startswith("rule_simulate_wildcards_")
        assert "rule simulate" in job_log.read_text()  # the job's own snakemake ran the case
    wildcards = sorted(r["comment"] for j, r in records.items() if j in simulate)
    assert all("slurm_pair" in w for w in wildcards)
    assert [float(re.search(r"restitution~([0-9.]+)", w).group(1)) for w in wildcards] == RESTITUTIONS
