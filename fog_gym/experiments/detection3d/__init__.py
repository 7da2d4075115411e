"""The baseline 3D detector of Experiment 1: BEV encoding (:mod:`~fog_gym.experiments.detection3d.bev`, numpy) and a CenterNet-style
BEV network (:mod:`~fog_gym.experiments.detection3d.model`, the ``torch`` extra)."""
