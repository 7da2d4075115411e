"""A content digest of a FogDrive dataset: whether two copies (say, regenerated in two sessions) hold the same data.

A study that spans sessions regenerates its dataset from the documented command; scenes regenerate bit for bit
from their seeds, but only while the code that renders them does not change. :func:`content_digest` hashes the
bytes of every file of the first and last sample of each chosen scene (every channel) in name order, so a study
record can refuse data that differs from the data its kept units were trained on, at the cost of reading two
samples per scene rather than the whole set.

Example:
    >>> from fog_gym.dataset.digest import content_digest
    >>> content_digest(None, [])[:15]  # no scenes: the digest of nothing
    'sha256:e3b0c442'
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import Any


def content_digest(ds: Any, scenes: Sequence[str]) -> str:
    """``sha256:<hex>`` over the channel files of the first and last sample of each scene in ``scenes`` (names of
    ``ds``, a :class:`~fog_gym.dataset.access.FogDrive`), in sorted name and channel order; a scene the dataset
    lacks is a ``KeyError`` naming it."""
    h = hashlib.sha256()
    for name in sorted(set(scenes)):
        scene = ds.get_scene_by_name(name)
        samples = ds.get_samples_for_scene(scene["token"])
        for sample in dict.fromkeys(s["token"] for s in (samples[0], samples[-1])):
            paths = ds.get_sample_paths(sample)
            for ch in sorted(paths):
                h.update(f"{name}|{ch}|".encode())
                h.update(paths[ch].read_bytes())
    return "sha256:" + h.hexdigest()
