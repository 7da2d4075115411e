"""Experiment 2 of the FogDrive paper: does defogging before detection beat training on fog?

Shaped like the other studies: :mod:`~.data` (chosen scenes, frames, images and boxes, training and evaluation
sets), :mod:`~.model` (a CenterNet 2D detector, pure PyTorch), :mod:`~.dehazers` (DCP, AOD-Net, the Koschmieder
oracle), :mod:`~.train` (a detector; AOD-Net), :mod:`~.evaluate` (COCO scores, image quality, pipelines A–D),
:mod:`~.report` (the paper's two tables, the figure), :mod:`~.study` (the study the runner drives and its command
line: ``fog-gym exp2``, ``python -m fog_gym.experiments.defog``). The ``exp`` extra.
"""
