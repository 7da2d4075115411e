"""Rasterisation kernels (numba). Pure functions over numpy arrays; nothing here knows the environment."""
