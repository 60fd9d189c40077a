"""numba kernels: plain functions on arrays, no Python objects (the driver lives in engine/)."""

from .cache import launch_threading_layer

# Before any kernel runs: a cached caller of the parallel contact kernel may lack the hook that
# starts the thread pool (docs/decisions/0022).
launch_threading_layer()
