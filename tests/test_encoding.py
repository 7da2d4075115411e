import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fog_gym.encoding import CITYSCAPES_PALETTE, SEMANTIC_TAGS, colorize_semantic, decode_depth, encode_depth


def test_depth_code_extremes():
    assert decode_depth(np.array([[[255, 255, 255]]], np.uint8))[0, 0] == pytest.approx(1000.0)
    assert decode_depth(np.array([[[0, 0, 0]]], np.uint8))[0, 0] == 0.0


@given(arrays(np.float32, (4, 5), elements=st.floats(0, 1000, width=32)))
@settings(max_examples=100, deadline=None)
def test_depth_roundtrip_sub_millimetre(depth):
    back = decode_depth(encode_depth(depth))
    np.testing.assert_allclose(back, depth, atol=1e-3, rtol=1e-6)


def test_depth_rejects_non_finite():
    with pytest.raises(ValueError, match="finite"):
        encode_depth(np.array([np.inf]))


def test_tags_are_carla_0914():
    assert SEMANTIC_TAGS["Car"] == 14 and SEMANTIC_TAGS["Truck"] == 15 and SEMANTIC_TAGS["Sky"] == 11
    assert SEMANTIC_TAGS["RoadLine"] == 24 and SEMANTIC_TAGS["GuardRail"] == 28
    assert tuple(colorize_semantic(np.array([14]))[0]) == (0, 0, 142)
    assert len(CITYSCAPES_PALETTE) == 29
