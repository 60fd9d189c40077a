"""numba's on-disk kernel cache, made safe for runs that start together (docs/decisions/0022).

numba stores a compiled caller together with the code of the kernels it calls, and the hook that
starts its thread pool (`reload_init`) only when the parallel kernel was compiled in the same
process: a caller compiled over a contact_forces_chunked *loaded from the cache* is saved without
it, and every later run that loads that caller calls into parallel code with no thread pool
(SIGSEGV). That happens when two runs compile into an empty cache at the same time (or a run was
stopped after some kernels were saved). Two guards:

- launch_threading_layer(): start the pool before any kernel runs, so such an entry is harmless;
- compile_lock(): an exclusive lock next to the cache, held by a run while it compiles or loads
  the kernels, so a second run waits and then loads complete entries from one process.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import time
from pathlib import Path

import numba

LOCK_NAME = "plugsim-kernels.lock"
KERNELS = Path(__file__).resolve().parent
# The declaration of the kernels' named parameters: numba compiles p.friction_pair into a position
# in the named tuple, and its cache key names the tuple's class, not its fields
PARAMETERS = KERNELS.parent / "parameters.py"


def kernel_source_digest(folder: Path = KERNELS, parameters: Path = PARAMETERS) -> str:
    """12 hex digits of the SHA-256 of every kernel module's source and of the parameter
    declaration (name and bytes)."""
    digest = hashlib.sha256()
    for path in [*sorted(folder.glob("*.py")), parameters]:
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:12]


def use_source_keyed_cache() -> Path:
    """Point numba's cache at a folder named after kernel_source_digest(), under NUMBA_CACHE_DIR
    if set, else engine/kernels/__pycache__: any edit of a kernel module starts a new cache.
    Must run before the kernel modules are imported (numba reads it when it decorates)."""
    base = Path(os.environ.get("NUMBA_CACHE_DIR") or KERNELS / "__pycache__")
    folder = base / f"kernels-{kernel_source_digest()}"
    numba.config.CACHE_DIR = str(folder)
    return folder


def launch_threading_layer() -> None:
    """Start numba's threading layer (what a parallel kernel's load hook does)."""
    numba.get_num_threads()


def cache_dir() -> Path | None:
    """The directory numba caches the contact kernels in (NUMBA_CACHE_DIR's subfolder for this
    checkout, else engine/kernels/__pycache__); None if numba's internals changed."""
    from .contacts import evaluate_contacts
    try:
        return Path(evaluate_contacts._cache.cache_path)
    except AttributeError:
        return None


@contextlib.contextmanager
def compile_lock(on_wait=None):
    """Hold an exclusive inter-process lock (fcntl.flock) on LOCK_NAME in cache_dir().

    If another process holds it, on_wait() is called once and this waits. Yields the seconds
    waited. Without a usable cache directory (unknown numba internals, read-only tree) it does not
    lock: numba then caches nothing there either."""
    folder = cache_dir()
    try:
        if folder is None:
            raise OSError("no cache directory")
        folder.mkdir(parents=True, exist_ok=True)
        handle = open(folder / LOCK_NAME, "a")
    except OSError:
        yield 0.0
        return
    with handle:
        started = time.monotonic()
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if on_wait is not None:
                on_wait()
            fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield time.monotonic() - started
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
