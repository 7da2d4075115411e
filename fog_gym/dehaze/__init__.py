"""Dehazers: tools a user applies to any uint8 RGB image, not perception of the simulated world.

* :mod:`~fog_gym.dehaze.classical` (numpy + OpenCV): He et al.'s Dark Channel Prior (:func:`dcp`) and the
  Koschmieder oracle (:func:`oracle`: the exact inverse of fog-gym's camera fog given depth, extinction and
  airlight — the upper bound of any dehazer);
* :mod:`~fog_gym.dehaze.aodnet` (the ``torch`` extra): AOD-Net (Li et al., ICCV 2017) and its training;
* :mod:`~fog_gym.dehaze.dehazeformer` (the ``torch`` extra): DehazeFormer (Song et al., IEEE TIP 2023) and its
  training.

Example:
    >>> import numpy as np
    >>> from fog_gym.dehaze import dcp
    >>> dcp(np.full((32, 32, 3), 120, np.uint8)).shape
    (32, 32, 3)
"""

from fog_gym.dehaze.classical import check_image, dcp, estimate_airlight, guided_filter, oracle

__all__ = ["check_image", "dcp", "estimate_airlight", "guided_filter", "oracle"]
