"""Evaluation metrics (pure numpy/numba): :mod:`fog_gym.metrics.detection3d` for 3D detection."""
