"""Experiment 1 of the FogDrive paper: does mixing fog densities at training time make a 3D detector more robust?

Shaped like the other studies: :mod:`~.protocol` and :mod:`~.data` (the paper's subsets; sweeps as training items),
:mod:`~.bev` and :mod:`~.model` (the baseline BEV detector, pure PyTorch), :mod:`~.train` (one row, one seed),
:mod:`~.evaluate` (metrics per test fog), :mod:`~.report` (matrices, heatmaps), :mod:`~.study` (the study the
runner drives and its command line: ``fog-gym exp1``, ``python -m fog_gym.experiments.detection3d``). The ``torch``
extra (``exp`` for the report).
"""
