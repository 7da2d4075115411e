"""fog-gym's performance benchmarks, part of the package so that ``fog-gym bench`` runs from an installed wheel:
:mod:`~.env` (FogDrive-v0 per stage against bare highway-env), :mod:`~.sensors` (point sensors, ground truth, night
cameras), :mod:`~.fog` (camera and LiDAR fog), :mod:`~.dataset` (recording, ``fog-gym generate``), :mod:`~.suite`
(all of them: ``fog-gym bench``), :mod:`~.common` (timing and tables). They report numbers and never assert a timing.
"""
