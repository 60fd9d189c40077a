"""numba kernels: plain functions on arrays, no Python objects (the driver lives in engine/)."""

from .cache import launch_threading_layer, use_source_keyed_cache

# Before any kernel is decorated: numba validates a cached kernel against its own source file
# only, so an edit of a kernel it calls (laws.py) would leave the old code in use; the cache
# folder is named after every kernel source instead (docs/decisions/0023).
use_source_keyed_cache()
# Before any kernel runs: a cached caller of the parallel contact kernel may lack the hook that
# starts the thread pool (docs/decisions/0022).
launch_threading_layer()
