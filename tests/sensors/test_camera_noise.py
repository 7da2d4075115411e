"""Camera noise (EMVA 1288 linear model) and motion blur: the statistics of the model, determinism, the env and the
fog wrapper (fog before the sensor), and bad configurations."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.envs.fogdrive import FogDriveEnv
from fog_gym.geometry import Pose
from fog_gym.sensors.camera import CameraConfig
from fog_gym.sensors.camera_noise import (DEFAULT_NOISE, TABLE_SIZE, CameraNoise, NoiseLaw, add_noise, add_noise_many,
                                          frame_key, level_signal, noise_law, noise_laws, noise_table, parse_noise,
                                          predicted_variance)  # fmt: skip
from fog_gym.sensors.motion_blur import blur_motion, image_flow
from fog_gym.wrappers import FogWrapper


def _moments(row: np.ndarray) -> tuple[float, float]:
    r = row.astype(np.float64)
    return float(r.mean()), float(r.var())


@pytest.mark.parametrize("night, gain", [(False, 1.0), (True, 1.0), (True, 4.0), (True, 16.0)])
def test_table_moments_match_the_emva_model_in_the_linear_range(night, gain):
    table = noise_table(DEFAULT_NOISE, gain, night)
    for level in (20, 40, 64, 100, 140):
        sd = predicted_variance(DEFAULT_NOISE, level, gain, night) ** 0.5
        if level - 3.5 * sd < 0 or night and level + 3.5 * sd > 153:
            continue  # the model holds in the linear part of the encoding, away from black (and the night shoulder)
        mean, var = _moments(table[level])
        assert abs(mean - level) < 0.06 + 0.01 * level**0.5
        assert var == pytest.approx(predicted_variance(DEFAULT_NOISE, level, gain, night), rel=0.04)


def test_night_frames_are_noisier_and_noise_grows_with_the_exposure_gain():
    sd = [np.sqrt(_moments(noise_table(DEFAULT_NOISE, g, n)[80])[1]) for n, g in ((False, 1.0), (True, 1.0), (True, 4.0), (True, 16.0))]
    assert sd == sorted(sd) and sd[1] > 2 * sd[0]
    # shot noise: at fixed gain the variance grows linearly with the signal (K²·μ_e), the read noise sets the floor
    table = noise_table(DEFAULT_NOISE, 4.0, True)
    v1, v2 = _moments(table[30])[1], _moments(table[120])[1]
    k = 255 * DEFAULT_NOISE.gain(4.0, True) / DEFAULT_NOISE.full_well_e
    assert (v2 - v1) / 90 == pytest.approx(k, rel=0.05)  # slope of variance over level = K [DN per electron]


def test_low_light_table_is_the_poisson_gaussian_law_itself():
    """Few electrons: the table's distribution equals a Monte-Carlo draw of Poisson + read noise, rounded."""
    noise = CameraNoise(full_well_e=2000.0, read_noise_e=1.5, night_gain=8.0)
    gain, level = 2.0, 12  # A = 16: 1 DN = 0.49 e-, mean 6 electrons
    rng = np.random.default_rng(0)
    lam = level_signal(np.array([level]), True)[0] * noise.full_well_e / noise.gain(gain, True)
    n = rng.poisson(lam, 400_000) + rng.normal(0.0, noise.read_noise_e, 400_000)
    dn = np.clip(np.floor(n * 255 * noise.gain(gain, True) / noise.full_well_e + 0.5), 0, 255)  # linear below the knee
    mc = np.bincount(dn.astype(int), minlength=256) / dn.size
    tab = np.bincount(noise_table(noise, gain, True)[level], minlength=256) / TABLE_SIZE
    assert np.abs(np.cumsum(mc) - np.cumsum(tab)).max() < 0.004  # Kolmogorov distance: table resolution 1/4096


@settings(max_examples=25, deadline=None)
@given(full=st.floats(300, 50_000), read=st.floats(0, 20), gain=st.floats(1, 16), night=st.booleans())
def test_tables_are_quantile_functions_ordered_by_level(full, read, gain, night):
    table = noise_table(CameraNoise(full_well_e=full, read_noise_e=read), gain, night).astype(np.int16)
    assert (np.diff(table, axis=1) >= 0).all()  # each row a quantile function
    assert (np.diff(table, axis=0) >= 0).all()  # a brighter pixel reads brighter at every quantile


def test_kernel_draws_follow_the_table_and_are_reproducible_and_independent():
    table = noise_table(DEFAULT_NOISE, 4.0, True)
    img = np.full((400, 500, 3), 64, np.uint8)
    a = add_noise(img, table, frame_key(5, 1, 0, 0))
    assert (add_noise(img, table, frame_key(5, 1, 0, 0)) == a).all()
    b = add_noise(img, table, frame_key(5, 1, 0, 3))
    assert (a != b).mean() > 0.8  # another variant, other draws
    mean, var = _moments(table[64])
    x = a.astype(np.float64)
    assert x.mean() == pytest.approx(mean, abs=0.05) and x.var() == pytest.approx(var, rel=0.02)
    r = x.reshape(-1, 3) - x.mean()
    assert abs(np.corrcoef(r[:, 0], r[:, 1])[0, 1]) < 0.01  # channels, and neighbours, independent
    assert abs(np.corrcoef(x[:, :-1, 0].ravel(), x[:, 1:, 0].ravel())[0, 1]) < 0.01
    assert (img == 64).all()  # the input is not changed


def _hash32(i: np.ndarray, key: int) -> np.ndarray:
    """The kernels' 32-bit hash in numpy: i ^ k1 through two multiply–xorshift rounds, k2 added between them."""
    k1, k2 = np.uint32(key & 0xFFFFFFFF), np.uint32(key >> 32)
    x = i.astype(np.uint32) ^ k1
    x = (x ^ (x >> np.uint32(16))) * np.uint32(0x7FEB352D) + k2
    x = (x ^ (x >> np.uint32(15))) * np.uint32(0x846CA68B)
    return x ^ (x >> np.uint32(16))


def _reference_noise(img: np.ndarray, table: np.ndarray, key: int) -> np.ndarray:
    """The kernel's draws in numpy: pixel p (row-major) hashes p with the 32-bit hash; bits 0-9, 11-20 and 22-31 are
    its red, green and blue quantiles."""
    z = _hash32(np.arange(img.shape[0] * img.shape[1], dtype=np.uint32), key)
    m = np.uint32(TABLE_SIZE - 1)
    u = np.stack([(z >> np.uint32(s)) & m for s in (0, 11, 22)], axis=1).astype(np.intp)
    return table[img.reshape(-1, 3), u].reshape(img.shape)


@settings(max_examples=20, deadline=None)
@given(st.integers(1, 90), st.integers(1, 90), st.integers(0, 2**64 - 1), st.integers(0, 2**32))
def test_kernel_is_the_32_bit_hash_over_the_pixels_on_one_thread_and_in_parallel(h, w, key, seed):
    from fog_gym.sensors.camera_noise import _noise_kernel, _noise_kernel_serial

    img = np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)
    table = noise_table(DEFAULT_NOISE, 2.0, True)
    want = _reference_noise(img, table, key)
    assert (add_noise(img, table, key) == want).all()
    for kernel in (_noise_kernel, _noise_kernel_serial):  # every span split: fewer pixels than spans too
        assert (_run(kernel, [img], [NoiseLaw(table)], [key])[0] == want).all()


def _run(kernel, imgs, laws, keys):
    outs = [np.empty_like(x) for x in imgs]
    kernel(tuple(x.reshape(-1) for x in imgs), tuple(o.reshape(-1) for o in outs),
           tuple(law.table.reshape(-1) for law in laws), np.array(keys, np.uint64))
    return outs


@settings(max_examples=20, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 70), st.integers(1, 70), st.booleans()), min_size=1, max_size=4),
       st.integers(0, 2**64 - 1), st.integers(0, 2**32))  # fmt: skip
def test_day_and_night_images_in_one_launch_each_follow_the_numpy_reference(shapes, key, seed):
    from fog_gym.sensors.camera_noise import _noise_kernel, _noise_kernel_serial

    rng = np.random.default_rng(seed)
    day, night = noise_law(DEFAULT_NOISE, 1.0, False), noise_law(DEFAULT_NOISE, 2.0, True)
    imgs = [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for h, w, _ in shapes]
    laws = [day if by_day else night for _, _, by_day in shapes]
    keys = [(key + 7919 * i) % 2**64 for i in range(len(imgs))]
    want = [_reference_noise(x, law.table, k) for x, law, k in zip(imgs, laws, keys)]
    assert all((a == b).all() for a, b in zip(add_noise_many(imgs, laws, keys), want))
    for kernel in (_noise_kernel, _noise_kernel_serial):
        assert all((a == b).all() for a, b in zip(_run(kernel, imgs, laws, keys), want))


def test_day_and_night_laws_are_the_exact_tables():
    for gain, night in ((1.0, False), (1.0, True), (4.0, True), (16.0, True)):
        assert (noise_law(DEFAULT_NOISE, gain, night).table == noise_table(DEFAULT_NOISE, gain, night)).all()
    few = CameraNoise(full_well_e=600.0)  # a grey level is a couple of electrons: the table is the law all the same
    assert (noise_law(few, 1.0, False).table == noise_table(few, 1.0, False)).all()


def _reference_quantiles(cdf: np.ndarray) -> np.ndarray:
    """The table of a law's CDF in numpy: quantile m's level counts the thresholds d with ceil(F_d·M − ½) <= m."""
    first = np.clip(np.ceil(cdf * TABLE_SIZE - 0.5), 0, TABLE_SIZE).astype(np.int64)
    return (first[..., None, :] <= np.arange(TABLE_SIZE)[:, None]).sum(-1).astype(np.uint8)


@settings(max_examples=15, deadline=None)
@given(full=st.floats(300, 50_000), read=st.one_of(st.just(0.0), st.floats(0.1, 20)), night=st.booleans(),
       gains=st.lists(st.floats(0.5, 16), min_size=1, max_size=4))  # fmt: skip
def test_a_frames_laws_computed_together_are_each_computed_alone(full, read, night, gains):
    """One launch for a frame's cameras (parallel and serial twins alike) gives each camera's own law, its table the
    quantiles of its CDF (a numpy reference), its CDF a distribution function within [0, 1]."""
    from fog_gym.sensors.camera_noise import _exact_cdf, _exact_cdfs
    from fog_gym.sensors.poisson_gauss import _cdf_tables, _cdf_tables_serial, _quantile_rows, _quantile_rows_serial

    noise = CameraNoise(full_well_e=full, read_noise_e=read)
    together = noise_laws([noise] * len(gains), gains, night)
    cdfs = _exact_cdfs([noise] * len(gains), gains, night)
    for gain, law, cdf in zip(gains, together, cdfs):
        alone = noise_law(noise, gain, night)
        assert (law.table == alone.table).all()
        assert (cdf == _exact_cdf(noise, gain, night)).all() and (cdf >= 0).all() and (cdf <= 1).all()
        assert (np.diff(cdf, axis=1) >= -1e-12).all()
        assert (law.table == _reference_quantiles(cdf)).all()
    rows = np.ascontiguousarray(cdfs.reshape(-1, 255))
    assert (_quantile_rows(rows, TABLE_SIZE) == _quantile_rows_serial(rows, TABLE_SIZE)).all()
    lam = np.random.default_rng(0).uniform(0, full, (len(gains), 256))
    t = np.sort(np.random.default_rng(1).uniform(-1, full, (len(gains), 255)), axis=1)
    sigma = np.full(len(gains), read)
    assert (_cdf_tables(lam, t, sigma) == _cdf_tables_serial(lam, t, sigma)).all()


def test_noise_laws_wants_a_gain_per_sensor():
    assert noise_laws([], [], False) == []
    with pytest.raises(ValueError, match="noises and gains must be as many"):
        noise_laws([DEFAULT_NOISE], [1.0, 2.0], False)


@settings(max_examples=30, deadline=None)
@given(gain=st.one_of(st.floats(max_value=0.0), st.just(float("nan")), st.just(float("inf")),
                      st.sampled_from(["", "x"]), st.booleans(), st.none()),
       night=st.booleans())  # fmt: skip
def test_a_gain_that_is_not_a_positive_finite_number_is_a_one_line_error_before_any_table(gain, night):
    for call in (lambda: noise_table(DEFAULT_NOISE, gain, night), lambda: noise_law(DEFAULT_NOISE, gain, night),
                 lambda: noise_laws([DEFAULT_NOISE], [gain], night),
                 lambda: predicted_variance(DEFAULT_NOISE, 100, gain, night)):  # fmt: skip
        with pytest.raises(ValueError, match="gain must") as err:
            call()
        assert "\n" not in str(err.value)


@pytest.mark.parametrize("call, match", [
    (lambda: noise_law("default", 1.0, False), "noise must be a CameraNoise"),
    (lambda: predicted_variance(DEFAULT_NOISE, 300, 1.0), "level must lie in"),
    (lambda: predicted_variance(DEFAULT_NOISE, -1, 1.0), "level must lie in"),
    (lambda: add_noise(np.zeros((2, 2, 3), np.uint8), noise_table(DEFAULT_NOISE, 1.0, False), "x"), "keys must be"),
    (lambda: add_noise(np.zeros((2, 2, 3), np.uint8), noise_table(DEFAULT_NOISE, 1.0, False), True), "keys must be"),
])  # fmt: skip
def test_a_sensor_a_level_or_a_key_of_the_wrong_kind_is_a_one_line_error(call, match):
    with pytest.raises(ValueError, match=match) as err:
        call()
    assert "\n" not in str(err.value)


def test_the_docs_contrast_table_is_the_noise_tables_own_standard_deviation():
    """docs/sensors.md's table of what noise does to the 5 % rule, row by row: σ of one pixel from the table at the
    background level B and total gain A (1 by day, night_gain · g at night), the contrast of one σ on B, and the pixels
    a 5 % contrast needs for a contrast-to-noise ratio of 5 when averaged."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "sensors.md").read_text()
    table = text[text.index("| scene | background level B |"):].split("\n\n")[0].splitlines()[2:]
    assert len(table) == 5
    for row in table:
        scene, level, a, sd, contrast, pixels = (c.strip() for c in row.strip("|").split("|"))
        night, level, a = scene.startswith("night"), int(level), float(a)
        got = noise_table(DEFAULT_NOISE, a / DEFAULT_NOISE.night_gain if night else a, night)[level].std()
        assert f"{got:.{len(sd.split('.')[1])}f}" == sd, row
        c = 100 * got / level
        assert f"{c:.1f} %" == contrast if c < 10 else f"{c:.0f} %" == contrast, row
        assert f"{round((5 * got / (0.05 * level)) ** 2):,}".replace(",", " ") == pixels, row


@given(g=st.floats(0.05, 64.0), night=st.booleans(), step=st.sampled_from([1 / 16, 1 / 8, 1 / 3, 1.0]))
def test_the_gain_lies_on_the_sensors_grid_nearest_the_continuous_gain(g, night, step):
    noise = CameraNoise(gain_step_ev=step)
    exact = CameraNoise(gain_step_ev=0.0).gain(g, night)
    a = noise.gain(g, night)
    assert exact == g * (8.0 if night else 1.0)
    assert abs(np.log2(a) - np.log2(exact)) <= step / 2 + 1e-12  # the nearest step: within half a step
    assert np.log2(a) / step == pytest.approx(round(np.log2(a) / step), abs=1e-9)  # a step of the grid
    assert noise.gain(2.0 ** (round(np.log2(exact) / step) * step) / (8.0 if night else 1.0), night) == pytest.approx(a)
    assert noise.gain(1.0, False) == 1.0 and noise.gain(4.0, True) == 32.0  # powers of two lie on grids of 1/n stops


def test_frames_whose_gains_round_to_one_step_share_one_law_computed_once(monkeypatch):
    import fog_gym.sensors.camera_effects as effects

    calls = []
    real = effects.noise_laws
    monkeypatch.setattr(effects, "noise_laws", lambda n, g, night: (calls.append(list(g)), real(n, g, night))[1])
    monkeypatch.setattr(effects, "_LAWS", type(effects._LAWS)())
    fx = effects.CameraEffects([CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 8, 6, noise="default")])
    other = effects.CameraEffects([CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 8, 6, noise="default")])
    a = fx.laws([DEFAULT_NOISE, DEFAULT_NOISE], [3.0, 3.01], True)  # 23.6 and 23.7: one step of 1/16 EV
    b = other.laws([DEFAULT_NOISE], [2.99], True)  # another rig of the process: the same law
    c = fx.laws([DEFAULT_NOISE], [3.3], True)  # 26.4: another step
    assert a[0] is a[1] is b[0] and c[0] is not a[0] and calls == [[3.0], [3.3]]
    assert (a[0].table == noise_law(DEFAULT_NOISE, 3.0, True).table).all()
    assert (a[0].table == noise_law(DEFAULT_NOISE, 3.01, True).table).all()  # the law of the step, from either gain


def test_bad_noise_configs_are_one_line_errors_naming_the_field():
    for kwargs, field in (({"full_well_e": 0}, "full_well_e"), ({"read_noise_e": -1}, "read_noise_e"),
                          ({"night_gain": 0.5}, "night_gain"), ({"motion_blur": 1}, "motion_blur"),
                          ({"exposure_s": (0.0, 0.03)}, "exposure_s"), ({"full_well_e": float("nan")}, "full_well_e"),
                          ({"gain_step_ev": -0.1}, "gain_step_ev"), ({"gain_step_ev": 2.0}, "gain_step_ev"),
                          ({"gain_step_ev": float("inf")}, "gain_step_ev")):  # fmt: skip
        with pytest.raises(ValueError, match=field) as err:
            CameraNoise(**kwargs)
        assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match="camera_noise"):
        parse_noise("loud")
    with pytest.raises(ValueError, match="noise"):
        CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 8, 6, noise=3)
    with pytest.raises(ValueError, match="camera_noise"):
        FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT"], camera_noise="loud")


@settings(max_examples=40, deadline=None)
@given(st.one_of(st.integers(), st.text(max_size=6), st.floats(), st.lists(st.integers(), max_size=2)))
def test_anything_but_none_a_preset_or_a_cameranoise_is_refused(value):
    if value is None or value in ("default",):
        return
    with pytest.raises(ValueError, match="camera_noise"):
        parse_noise(value)


def test_still_world_has_no_flow_and_blur_keeps_a_linear_ramp():
    K = np.array([[100.0, 0, 40], [0, 100.0, 30], [0, 0, 1]])
    depth = np.full((60, 80), 12.0, np.float32)
    inst = np.zeros((60, 80), np.uint16)
    flow = image_flow(depth, inst, K, np.eye(4), np.zeros((1, 3)), np.zeros(3), 0.03)
    assert not flow.any()
    img = np.random.default_rng(0).integers(0, 256, (60, 80, 3), dtype=np.uint8)
    assert (blur_motion(img, flow) == img).all()
    ramp = np.repeat(np.repeat((np.arange(80) * 3).astype(np.uint8)[None, :, None], 60, 0), 3, 2)
    f = np.zeros((60, 80, 2), np.float32)
    f[..., 0] = 6.0
    out = blur_motion(ramp, f)
    assert (out[:, 5:-5] == ramp[:, 5:-5]).all()  # a linear ramp averaged symmetrically along x stays itself


def test_forward_motion_expands_from_the_centre_and_vehicles_move_by_their_own_velocity():
    K = np.array([[100.0, 0, 40], [0, 100.0, 30], [0, 0, 1]])
    depth = np.full((60, 80), 10.0, np.float32)
    inst = np.zeros((60, 80), np.uint16)
    inst[:, 60:] = 2  # a vehicle on the right, driving along with the camera
    vel = np.array([[0.0, 0, 0], [0, 0, 0], [0, 0, 20.0]])
    flow = image_flow(depth, inst, K, np.eye(4), vel, np.array([0.0, 0, 20.0]), 0.05)  # optical z forward
    assert abs(flow[30, 40]).max() < 0.1  # the focus of expansion
    assert flow[30, 10, 0] < -1 and flow[30, 50, 0] > 0  # the static world streams outward
    assert not flow[:, 60:].any()  # the vehicle keeps its place in the image


@pytest.fixture(scope="module")
def noisy_pair():
    def make(noise, tod):
        return FogWrapper(FogDriveEnv(town="merge", resolution=(96, 72), cameras=["CAM_FRONT", "CAM_LEFT"],
                                      time_of_day=tod, camera_noise=noise), fog=["light", "dense"])  # fmt: skip
    return make


@pytest.mark.parametrize("tod", ["day", "night"])
def test_env_records_the_clean_light_through_the_sensor_and_fog_comes_before_the_noise(noisy_pair, tod):
    clean_env, noisy_env = noisy_pair(None, tod), noisy_pair("default", tod)
    ref, _ = clean_env.reset(seed=11)
    obs, _ = noisy_env.reset(seed=11)
    base = noisy_env.unwrapped
    for cam in ("CAM_FRONT", "CAM_LEFT"):
        assert (base.frames[cam].rgb == ref[cam]).all()  # the frames keep the noise-free light
        assert (obs[cam] == base.camera_record(cam, ref[cam], 0)).all()
        for lv in ("LIGHT", "DENSE"):  # the fogged light of the noise-free env, recorded through the sensor
            key = f"{cam}_FOG_{lv}"
            variant = noisy_env.fog[0 if lv == "LIGHT" else 1]
            from fog_gym.wrappers.fog import _level_key

            assert (obs[key] == base.camera_record(cam, ref[key], _level_key(variant) + 1)).all()
            assert (obs[key] != obs[cam]).any()
        assert obs[f"{cam}_DEPTH"] is not None and (obs[f"{cam}_DEPTH"] == ref[f"{cam}_DEPTH"]).all()
    again, _ = noisy_env.reset(seed=11)
    assert all((again[k] == obs[k]).all() for k in obs)
    other, _ = noisy_env.reset(seed=12)
    assert (other["CAM_FRONT"] != obs["CAM_FRONT"]).any()


def test_night_recording_is_noisier_than_day():
    sds = {}
    for tod in ("day", "night"):
        env = FogDriveEnv(town="merge", resolution=(96, 72), cameras=["CAM_FRONT"], time_of_day=tod, camera_noise="default")
        obs, _ = env.reset(seed=3)
        d = obs["CAM_FRONT"].astype(float) - env.frames["CAM_FRONT"].rgb
        mid = (env.frames["CAM_FRONT"].rgb > 10) & (env.frames["CAM_FRONT"].rgb < 150)
        sds[tod] = (d[mid] / np.sqrt(env.frames["CAM_FRONT"].rgb[mid].astype(float))).std()  # per unit shot noise
    assert sds["night"] > 2 * sds["day"]


@settings(max_examples=30, deadline=None)
@given(st.sampled_from(["lengths", "empty", "dtype", "shape", "table", "law"]))
def test_bad_images_laws_and_keys_are_one_line_errors_before_any_draw(case):
    law = noise_law(DEFAULT_NOISE, 1.0, False)
    img = np.zeros((4, 5, 3), np.uint8)
    args, match = {
        "lengths": (([img, img], [law], [1]), "as many"),
        "empty": (([], [], []), "non-empty"),
        "dtype": (([img.astype(np.float32)], [law], [1]), "uint8 image"),
        "shape": (([img[..., :2]], [law], [1]), "uint8 image"),
        "table": (([img], [np.zeros((256, 7), np.uint8)], [1]), "noise table"),
        "law": (([img], [NoiseLaw(np.zeros((3, 3)))], [1]), "noise table"),
    }[case]
    with pytest.raises(ValueError, match=match) as err:
        add_noise_many(*args)
    assert "\n" not in str(err.value)
