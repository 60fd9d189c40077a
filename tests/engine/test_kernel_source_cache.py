"""The kernels' numba cache is keyed on every kernel source (engine/kernels/cache.py): numba alone
checks a cached kernel against its own file only, so an edit of a kernel it calls went unseen."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from engine.kernels import cache

ROOT = Path(__file__).resolve().parents[2]


def test_an_edit_of_any_kernel_module_changes_the_cache_folder(tmp_path):
    copy = tmp_path / "kernels"
    shutil.copytree(cache.KERNELS, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = cache.kernel_source_digest(copy)
    assert cache.kernel_source_digest(copy) == before  # deterministic
    laws = copy / "laws.py"
    laws.write_text(laws.read_text() + "\n# an edit of a callee only\n")
    assert cache.kernel_source_digest(copy) != before


def test_the_kernels_cache_under_the_digest_folder_and_numba_cache_dir_is_respected(tmp_path):
    code = ("import numba, engine.kernels.contacts as c; "
            "print(numba.config.CACHE_DIR); print(c.evaluate_contacts._cache.cache_path)")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    folder = tmp_path / f"kernels-{cache.kernel_source_digest()}"
    assert out[0] == str(folder)
    assert out[1].startswith(str(folder))
