"""The FogDrive writer's PNG encoder (fog_gym.dataset.png): lossless round trips through Pillow and OpenCV for every
channel kind the layout writes (RGB, fogged RGB, CARLA-encoded depth, CARLA semantic colours), over any content."""

import io

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from PIL import Image

from fog_gym.dataset.png import encode_png
from fog_gym.encoding import decode_depth, encode_depth, semantic_to_carla_rgb


def decoded(png: bytes) -> tuple[np.ndarray, np.ndarray]:
    """The pixels as Pillow and as OpenCV (its BGR turned to RGB) read them."""
    pil = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
    ocv = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)[..., ::-1]
    return pil, ocv


@given(arrays(np.uint8, st.tuples(st.integers(1, 40), st.integers(1, 40), st.just(3))))
@settings(max_examples=60, deadline=None)
def test_any_rgb_image_decodes_to_the_same_pixels_in_pillow_and_opencv(rgb):
    pil, ocv = decoded(encode_png(rgb))
    assert np.array_equal(pil, rgb) and np.array_equal(ocv, rgb)


@given(arrays(np.float32, (12, 17), elements=st.floats(0.0, 1000.0, width=32)))
@settings(max_examples=30, deadline=None)
def test_depth_survives_its_carla_colours_and_the_png(depth):
    colours = encode_depth(depth)
    pil, ocv = decoded(encode_png(colours))
    assert np.array_equal(pil, colours) and np.array_equal(ocv, colours)
    assert np.array_equal(decode_depth(ocv), decode_depth(colours))


@given(arrays(np.uint8, (9, 13), elements=st.integers(0, 28)))
@settings(max_examples=30, deadline=None)
def test_semantic_colours_round_trip(labels):
    colours = semantic_to_carla_rgb(labels)
    pil, ocv = decoded(encode_png(colours))
    assert np.array_equal(pil, colours) and np.array_equal(ocv, colours)


def test_a_real_frame_round_trips_and_stays_within_one_and_a_half_times_opencvs_size():
    from fog_gym.envs.fogdrive import FogDriveEnv

    env = FogDriveEnv(town="merge", resolution=(320, 240), labels=None)
    obs, _ = env.reset(seed=0)
    env.close()
    for image in (obs["CAM_FRONT"], encode_depth(obs["CAM_FRONT_DEPTH"])):
        png = encode_png(image)
        pil, ocv = decoded(png)
        assert np.array_equal(pil, image) and np.array_equal(ocv, image)
        ok, ref = cv2.imencode(".png", image[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_FILTER,
                                                          cv2.IMWRITE_PNG_FILTER_NONE])  # fmt: skip
        assert len(png) <= 1.5 * len(ref)  # the previous writer's files


@pytest.mark.parametrize("bad", [np.zeros((4, 4), np.uint8), np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 3)),
                                 np.zeros((0, 4, 3), np.uint8)])  # fmt: skip
def test_anything_but_a_uint8_rgb_image_is_refused(bad):
    with pytest.raises(ValueError, match="uint8 \\(H, W, 3\\)"):
        encode_png(bad)
