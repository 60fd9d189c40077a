"""numba's kernel cache with runs that start together (docs/decisions/0022): a caller compiled over
a cached parallel kernel, as concurrent first runs leave it, loads and runs, bit-identical; the
compile lock makes a second run wait."""

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
STAGE = Path(__file__).with_name("cache_stage.py")


def _stage(name, cache):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, str(STAGE), name], capture_output=True, text=True, cwd=ROOT,
                          env=env, timeout=600)


@pytest.mark.slow
def test_a_caller_compiled_over_a_cached_parallel_kernel_loads_and_gives_the_same_forces(tmp_path):
    """Process 1 leaves only contact_forces_chunked in an empty cache (what a second run compiling
    at the same time, or a run stopped while compiling, leaves); process 2 compiles
    evaluate_contacts over it, loading that kernel, and numba saves evaluate_contacts without the
    hook that starts the thread pool; process 3 loads it: it crashed with SIGSEGV (every later
    warm start of the incident). Now its forces equal process 2's bit for bit. ~25 s CPU."""
    cache = tmp_path / "cache"
    first = _stage("chunked", cache)
    assert first.returncode == 0, first.stderr
    compiled = _stage("evaluate", cache)
    assert compiled.returncode == 0, compiled.stderr
    loaded = _stage("evaluate", cache)
    assert loaded.returncode == 0, f"exit {loaded.returncode} loading the cached caller: {loaded.stderr[-2000:]}"
    assert loaded.stdout.split() == compiled.stdout.split()
    assert len(compiled.stdout.split()) == 60 * 6 + 2 and any(float.fromhex(v) for v in compiled.stdout.split())


# holds the lock until the file argv[1] exists (the waiting process creates it), at most 60 s,
# so that the test does not depend on how fast the second process starts on a loaded machine
HOLD = """
import sys, time
from pathlib import Path
from engine.kernels.cache import compile_lock
flag = Path(sys.argv[1])
def waiting():
    print("waiting", flush=True)
    flag.touch()
with compile_lock(on_wait=waiting) as waited:
    print(f"locked {waited:.3f} {time.time():.3f}", flush=True)
    deadline = time.monotonic() + 60
    while sys.argv[2] == "hold" and not flag.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
print(f"released {time.time():.3f}", flush=True)
"""


def test_the_compile_lock_makes_a_second_run_wait_for_the_first(tmp_path):
    """Two processes on one cache directory: the second waits (and says so) until the first
    releases the lock; no kernel is compiled."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(ROOT))
    flag = tmp_path / "second-is-waiting"
    run = lambda hold: subprocess.Popen([sys.executable, "-c", HOLD, str(flag), hold], stdout=subprocess.PIPE,
                                        text=True, cwd=ROOT, env=env)
    a = run("hold")
    assert a.stdout.readline().startswith("locked")
    b = run("go")
    out_a, _ = a.communicate(timeout=60)
    out_b, _ = b.communicate(timeout=60)
    released = float(out_a.split()[-1])
    lines = out_b.splitlines()
    assert lines[0] == "waiting"
    _, waited, locked = lines[1].split()
    assert float(locked) >= released - 0.05 and float(waited) > 0.0, (out_a, out_b)
    assert list((tmp_path / "cache").rglob("plugsim-kernels.lock"))
