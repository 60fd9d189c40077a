"""numba kernels: plain functions on arrays, no Python objects (the driver lives in engine/)."""
