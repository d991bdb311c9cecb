"""Compiled kernels (numba, ``@njit`` only): flat float64 arrays in, status codes out."""
