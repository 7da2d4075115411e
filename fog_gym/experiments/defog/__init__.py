"""Experiment 2: defog-then-detect vs train-on-fog (a CenterNet 2D detector, :mod:`~fog_gym.experiments.defog.model`;
the protocol, :mod:`~fog_gym.experiments.defog.experiment`)."""
