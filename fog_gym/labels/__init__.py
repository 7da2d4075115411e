"""Ground truth: 3D boxes in the LiDAR frame and 2D boxes per camera (:mod:`fog_gym.labels.boxes`).

Example:
    >>> LabelConfig().visibility, LabelConfig().min_detect
    ('lidar', 5)
"""

from __future__ import annotations

from fog_gym.labels.boxes import (EXTRINSIC_KEYS, VISIBILITY_RULES, Annotations, CameraView, LabelConfig, annotate,
                                  boxes_2d, boxes_3d, empty_2d, pixel_counts, semantic_lidar_counts)  # fmt: skip

__all__ = ["EXTRINSIC_KEYS", "VISIBILITY_RULES", "Annotations", "CameraView", "LabelConfig", "annotate", "boxes_2d",
           "boxes_3d", "empty_2d", "pixel_counts", "semantic_lidar_counts"]  # fmt: skip
