"""Named random streams and the scene id: one definition each, stable values."""

import hashlib

import numpy as np
import pytest

from fog_gym.dataset.layout import scene_folder_name, scene_id
from fog_gym.seeds import SALTS, stream


def test_a_stream_is_the_seed_sequence_of_its_seed_and_salt():
    for name, salt in SALTS.items():
        expected = np.random.default_rng(np.random.SeedSequence([11, salt])).integers(0, 2**62, 4)
        assert (stream(11, name).integers(0, 2**62, 4) == expected).all()
    assert (stream(None, "world").random(3) == stream(0, "world").random(3)).all()
    assert stream(5, "fog", 1).random() != stream(5, "fog", 2).random()


def test_an_unknown_stream_is_refused_with_the_known_names():
    with pytest.raises(ValueError, match="unknown random stream 'traffic'.*fog"):
        stream(0, "traffic")


def test_scene_ids_are_the_recorded_hash_and_differ_per_run():
    assert scene_id(3, "night", 2, 99) == hashlib.sha256(b"3|night|2|99").hexdigest()[:8]
    assert scene_id(3, "night", 2, 99) != scene_id(3, "night", 3, 99)
    assert scene_folder_name(3, "night", 2, scene_id(3, "night", 2, 99)).endswith("_run2_" + scene_id(3, "night", 2, 99))
