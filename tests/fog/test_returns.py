"""LiDAR return modes: strongest is today's output; in clear air the three modes agree; last and dual recover every
hard target above the detection floor that the strongest echo loses to the fog; through the env, paired fog, fog
fields, generation, exports and the perceived objects' opt-in last-return rule."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.channels import pack_points, unpack_points
from fog_gym.fog import fog_lidar, parse_fog
from fog_gym.fog.returns import DETECTION_FLOOR, apply_returns, hard_intensity, homogeneous_tau


def _cloud(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    r = rng.uniform(2.0, 120.0, n)
    az, el = rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.35, 0.09, n)
    i = np.exp(-0.004 * r) * rng.uniform(0.2, 1.0, n)
    return np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), i].astype(np.float32)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 2000), st.sampled_from(["light", "moderate", "dense", 30.0]))
def test_last_and_dual_keep_every_hard_target_above_the_floor_that_the_strongest_echo_loses(seed, n, fog):
    clean = _cloud(seed, n)
    level = parse_fog(fog)
    strongest = fog_lidar(clean, level, np.random.default_rng(seed))
    tau = homogeneous_tau(clean, level.alpha)
    lost = (strongest[:, :3] != clean[:, :3]).any(1)  # the strongest echo is the fog's
    above = hard_intensity(clean, tau) >= DETECTION_FLOOR
    last = apply_returns(clean, strongest, tau, "last")
    dual = apply_returns(clean, strongest, tau, "dual")
    recovered = lost & above
    # last: the hard target where it is detected, the strongest echo elsewhere
    assert np.array_equal(last[recovered, :3], clean[recovered, :3])
    assert np.array_equal(last[~recovered], strongest[~recovered])
    # dual: the strongest rows in order (return 0), then one extra last echo per recovered beam (return 1)
    assert len(dual) == n + recovered.sum() and np.array_equal(dual[:n, :4], strongest) and (dual[:n, 4] == 0).all()
    assert np.array_equal(dual[n:, :3], clean[recovered, :3]) and (dual[n:, 4] == 1).all()
    assert np.allclose(dual[n:, 3], hard_intensity(clean[recovered], tau[recovered]) / 255.0)
    # nothing below the floor comes back, and a kept hard target is never doubled
    assert not (lost & ~above & (last[:, :3] == clean[:, :3]).all(1)).any()


def test_in_clear_air_the_three_modes_give_the_clean_sweep():
    clean = _cloud(0, 500)
    tau = np.zeros(500)
    assert np.array_equal(apply_returns(clean, clean, tau, "last"), clean)
    dual = apply_returns(clean, clean, tau, "dual")
    assert np.array_equal(dual[:, :4], clean) and (dual[:, 4] == 0).all()


def test_bad_modes_are_one_line_errors_naming_the_field():
    from fog_gym.sensors.lidar import LidarConfig

    with pytest.raises(ValueError, match=r"^returns must be one of \('strongest', 'last', 'dual'\), got 'first'$"):
        LidarConfig.fogdrive(returns="first")
    from fog_gym.perception.objects import ObjectsConfig

    with pytest.raises(ValueError, match="lidar_returns must be strongest or last"):
        ObjectsConfig(lidar_returns="dual")


@pytest.fixture(scope="module")
def envs():
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.wrappers import FogWrapper

    out = {}
    for mode in ("strongest", "last", "dual"):
        env = FogWrapper(FogDriveEnv(town="highway", resolution=(32, 24), cameras=["CAM_FRONT"], lidar_returns=mode),
                         ["dense"])  # fmt: skip
        obs, _ = env.reset(seed=5)
        out[mode] = (env, obs)
    return out


def test_the_env_names_the_channels_of_each_mode_and_strongest_is_unchanged(envs):
    _, so = envs["strongest"]
    _, lo = envs["last"]
    _, do = envs["dual"]
    assert "LIDAR_TOP" in so and "LIDAR_TOP_LAST" in lo and "LIDAR_TOP_DUAL" in do
    clean = unpack_points(so, "LIDAR_TOP")
    assert np.array_equal(unpack_points(lo, "LIDAR_TOP_LAST"), clean)  # clear air: one echo per beam
    dual_clean = unpack_points(do, "LIDAR_TOP_DUAL")
    assert np.array_equal(dual_clean[:, :4], clean) and (dual_clean[:, 4] == 0).all()
    assert do["LIDAR_TOP_DUAL"].shape == (2 * so["LIDAR_TOP"].shape[0], 5)
    strongest = unpack_points(so, "LIDAR_TOP_FOG_DENSE")
    last = unpack_points(lo, "LIDAR_TOP_LAST_FOG_DENSE")
    dual = unpack_points(do, "LIDAR_TOP_DUAL_FOG_DENSE")
    assert np.array_equal(dual[: len(strongest), :4], strongest)  # the same fog draws: the same strongest echoes
    extra = dual[len(strongest):]
    assert len(extra) > 0 and (extra[:, 4] == 1).all()
    changed = (last[:, :3] != strongest[:, :3]).any(1)
    assert changed.sum() == len(extra) and np.array_equal(last[changed, :3], extra[:, :3])


@pytest.mark.parametrize("mode", ["strongest", "dual"])
def test_the_fog_reads_the_envs_own_point_counts_with_the_bits_of_a_scan_of_the_channel(envs, mode, monkeypatch):
    """The env tells the fog how many leading rows of each point channel it packed are points (so the fog does not
    scan the channel's empty tail): the same fogged channels as unpacking; a channel a wrapper replaced is not told."""
    from fog_gym.fog.models import FogContext, model_for

    env, obs = envs[mode]
    base = env.unwrapped
    channel = "LIDAR_TOP" if mode == "strongest" else "LIDAR_TOP_DUAL"
    rows = base.point_rows(obs)
    assert rows[channel] == len(unpack_points(obs, channel)) == len(base.points[channel]) > 0
    assert channel not in base.point_rows({**obs, channel: obs[channel].copy()})  # not the array the env packed
    told, scanned = ({"dense": np.random.default_rng(3)} for _ in range(2))
    hahner = model_for("lidar")
    a = hahner.apply(obs, channel, [parse_fog("dense")], FogContext(rngs=told, lidar_returns=mode, point_rows=rows))
    b = hahner.apply(obs, channel, [parse_fog("dense")], FogContext(rngs=scanned, lidar_returns=mode))
    assert np.array_equal(a["dense"], b["dense"]) and a["dense"].shape == obs[channel].shape
    # and through the wrapper: a step with the counts equals one without them
    env.reset(seed=9)
    with_rows, _, _, _, _ = env.step(base.idle_action)
    monkeypatch.setattr(base, "point_rows", lambda obs: {})
    env.reset(seed=9)
    without, _, _, _, _ = env.step(base.idle_action)
    fogged = [k for k in with_rows if k.startswith(channel) and k.endswith("FOG_DENSE")]
    assert fogged and all(np.array_equal(with_rows[k], without[k]) for k in fogged)


def test_a_fog_field_gives_the_same_modes_with_its_optical_depth():
    """A bank of dense fog around the LiDAR: the strongest echoes are today's, and the last echoes come back where
    the hard target's echo through the bank's optical depth reaches the floor. (Deep inside a thin-edged bank the
    strongest echo is the fog's only where the target's echo is already below the floor: nothing to add there.)"""
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.fog.depth import field_pose
    from fog_gym.fog.fields import FogBank
    from fog_gym.fog.returns import field_tau
    from fog_gym.wrappers import FogWrapper

    bank = FogBank(50.0, start=0.5, length=300.0, edge=1.0, name="bank")
    out = {}
    for mode in ("strongest", "dual"):
        env = FogWrapper(FogDriveEnv(town="highway", resolution=(32, 24), cameras=["CAM_FRONT"], lidar_returns=mode),
                         [bank, "light"])  # fmt: skip
        obs, _ = env.reset(seed=2)
        out[mode] = (env, obs)
    env, so = out["strongest"]
    clean, strongest = unpack_points(so, "LIDAR_TOP"), unpack_points(so, "LIDAR_TOP_FOG_BANK")
    dual = unpack_points(out["dual"][1], "LIDAR_TOP_DUAL_FOG_BANK")
    assert np.array_equal(dual[: len(strongest), :4], strongest) and (dual[len(strongest):, 4] == 1).all()
    pose = field_pose(env.unwrapped.sensor_to_world("LIDAR_TOP"), env.field_frame)
    tau = field_tau(clean, bank, pose, env._field_time())
    lost = (strongest[:, :3] != clean[:, :3]).any(1)
    want = lost & (hard_intensity(clean, tau) >= DETECTION_FLOOR)
    assert want.sum() > 0 and len(dual) - len(strongest) == want.sum()
    assert np.array_equal(dual[len(strongest):, :3], clean[want, :3])


def test_generated_dual_sets_validate_and_export_every_echo(tmp_path):
    pytest.importorskip("nuscenes")
    from fog_gym.dataset import FogDrive
    from fog_gym.dataset.decode import load_channel
    from fog_gym.dataset.export import export
    from fog_gym.dataset.validate import validate
    from fog_gym.generate import generate, plan_scenes

    root = tmp_path / "dual"
    generate(root, plan_scenes(2, towns=("highway",), seed=1, resolution=(32, 24), seconds=0.2, lidar_returns="dual"),
             progress=False)  # fmt: skip
    assert validate(root) == []
    ds = FogDrive(root)
    assert {c for c in ds.list_channels() if "LIDAR" in c} >= {"LIDAR_TOP_DUAL", "LIDAR_TOP_DUAL_FOG_DENSE"}
    export(root, tmp_path / "k", "kitti", fog="dense", progress=False)
    s = ds.sample[-1]
    ch = "LIDAR_TOP_DUAL_FOG_DENSE"
    pts = load_channel(ch, ds.get_sample_paths(s["token"], [ch])[ch], ds.channels[ch])
    n_files = sorted((tmp_path / "k" / "training" / "velodyne").glob("*.bin"))
    sizes = [f.stat().st_size // 16 for f in n_files]
    assert len(pts) in sizes  # every echo of a dual sweep is a point of the export


def test_the_perceived_objects_last_return_rule_sees_a_car_behind_dense_fog():
    """Beyond the crossover range the strongest echo of every beam is the fog's; a last-return LiDAR still detects
    a bright car there while its echo reaches the detection floor."""
    from fog_gym.fog.lidar import BETA_PER_MOR, GAMMA, lidar_crossover_range, soft_response_table
    from fog_gym.perception import kernels as PK
    from fog_gym.perception.objects import ObjectsConfig

    dense = parse_fog("dense")
    cfg = ObjectsConfig()
    x = lidar_crossover_range(dense) + 8.0
    rows = [(0.0, 0.0, 4.8, 2.1, 1.5), (x, 0.0, 4.5, 1.9, 1.5)]
    a = np.array(rows)
    ti, tr = soft_response_table(dense.alpha)
    beta = BETA_PER_MOR / dense.visibility_m / (GAMMA / math.pi)
    az = np.arange(cfg.lidar_beams) * (2 * np.pi / cfg.lidar_beams) - np.pi
    counts = {}
    for last in (False, True):
        count, cen = np.zeros(2), np.zeros((2, 3))
        PK.lidar_detect(2, a[:, 0].copy(), a[:, 1].copy(), np.zeros(2), a[:, 2].copy(), a[:, 3].copy(), a[:, 4].copy(),
                        0.0, 0.0, 0.0, cfg.lidar_height, cfg.lidar_elevations(), np.cos(az), np.sin(az), cfg.lidar_range,
                        7, 0, dense.alpha, beta, ti, tr, 0.0, 0.0, 0.0, cfg.max_rays, count, cen, np.zeros((0, 8)),
                        np.zeros(3), np.zeros((1, 1)), np.zeros(1), np.zeros((1, 1)), np.zeros(1), 0.0, last)  # fmt: skip
        counts[last] = count[1]
    assert counts[False] == 0 and counts[True] >= cfg.min_points


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), alpha=st.floats(0.001, 0.2))
def test_homogeneous_alpha_path_equals_the_optical_depths(seed, alpha):
    from fog_gym.fog.returns import homogeneous_tau

    rng = np.random.default_rng(seed)
    clean = np.c_[rng.uniform(-80, 80, (300, 3)), rng.uniform(0, 1, 300)].astype(np.float32)
    strongest = clean.copy()
    fogged = rng.random(300) < 0.5
    strongest[fogged, :3] *= 0.3
    for mode in ("last", "dual"):
        assert np.array_equal(apply_returns(clean, strongest, None, mode, alpha=alpha),
                              apply_returns(clean, strongest, homogeneous_tau(clean, alpha), mode))
    with pytest.raises(ValueError, match="alpha"):
        apply_returns(clean, strongest, None, "last")


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), visibility=st.floats(20.0, 400.0))
def test_the_return_rule_packed_into_a_channel_equals_its_sweep_padded(seed, visibility):
    """``apply_returns(..., capacity=)`` writes the packed channel itself: the unpacked sweep padded with zero rows;
    a capacity that cannot hold the dual returns is refused."""
    rng = np.random.default_rng(seed)
    clean = np.c_[rng.uniform(-80, 80, (400, 3)), rng.uniform(0.01, 1, 400)].astype(np.float32)
    level = parse_fog(visibility)
    plain = fog_lidar(clean, level, np.random.default_rng(1))
    for mode in ("last", "dual"):
        by_alpha = apply_returns(clean, plain, None, mode, alpha=level.alpha)
        assert np.array_equal(by_alpha, apply_returns(clean, plain, homogeneous_tau(clean, level.alpha), mode))
        packed = apply_returns(clean, plain, None, mode, alpha=level.alpha, capacity=2 * len(clean) + 5)
        assert np.array_equal(packed, pack_points(by_alpha, len(packed)))
    with pytest.raises(ValueError, match="cannot hold the dual returns"):
        apply_returns(clean, plain, None, "dual", alpha=level.alpha, capacity=len(clean))
    with pytest.raises(ValueError, match="needs the optical depths tau"):
        apply_returns(clean, plain, None, "last")


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(1, 1500), fog=st.sampled_from(["clear", "light", "dense", 30.0]),
       mode=st.sampled_from(["strongest", "last", "dual"]), spare=st.integers(0, 50), reflect=st.booleans(),
       timed=st.booleans(), ignored=st.integers(0, 2))  # fmt: skip
def test_the_fused_fog_and_return_pass_equals_the_fog_then_the_rule(seed, n, fog, mode, spare, reflect, timed,
                                                                     ignored):  # fmt: skip
    """``fog_lidar_into`` (the fog and the return rule in one pass, into an uninitialised packed channel) gives, row
    for row, what ``fog_lidar`` then ``apply_returns(..., capacity=)`` give: every mode and fog, reflectance
    intensities, a ride-along time column, spare rows, trailing columns it is told to ignore (``columns=``: a dual
    sweep's own return column, read in place) — the LiDAR fog's own path against the reference."""
    from fog_gym.fog.lidar import fog_lidar_into

    clean = _cloud(seed, n)
    if timed:  # a continuous sweep's time column rides along with each beam
        clean = np.c_[clean, np.random.default_rng(seed).uniform(0, 0.1, n)].astype(np.float32)
    level = parse_fog(fog)
    reflectance = 0.004 if reflect else None
    strongest = fog_lidar(clean, level, np.random.default_rng(seed), reflectance=reflectance)
    dual = mode == "dual"
    capacity = (2 * n if dual else n) + spare
    if mode == "strongest":
        reference = pack_points(strongest, capacity)
    else:
        reference = apply_returns(clean, strongest, None, mode, alpha=level.alpha, capacity=capacity)
    channel = np.full((capacity, clean.shape[1] + dual), np.nan, np.float32)  # every row gets written
    given = np.c_[clean, np.full((n, ignored), 7.0, np.float32)]  # columns the pass must not read into its rows
    rows = fog_lidar_into(given, level, np.random.default_rng(seed), channel, mode, reflectance=reflectance,
                          columns=clean.shape[1] if ignored else None)  # fmt: skip
    assert np.array_equal(channel, reference)
    assert rows == len(unpack_points(channel, "LIDAR_TOP_DUAL" if dual else "LIDAR_TOP"))


@settings(max_examples=30, deadline=None)
@given(rows=st.integers(1, 3000), columns=st.integers(4, 6), start=st.integers(0, 3000))
def test_a_channels_tail_is_cleared_in_parallel_chunks_and_its_points_kept(rows, columns, start):
    """The packed channel's empty tail after the points is cleared by a parallel kernel for large tails (a dual
    channel's 1.9 MB): both twins zero exactly the rows from ``start`` on and leave the rows before it as they were."""
    from fog_gym.fog.lidar import _zero_rows, _zero_rows_serial

    start = min(start, rows)
    before = np.random.default_rng(rows).uniform(-5, 5, (rows, columns)).astype(np.float32)
    for kernel in (_zero_rows, _zero_rows_serial):
        channel = before.copy()
        channel[start:] = np.nan
        kernel(channel, start)
        assert np.array_equal(channel[:start], before[:start]) and not channel[start:].any()


def test_a_large_dual_channel_is_written_whole_with_its_tail_cleared_in_parallel():
    from fog_gym.fog.lidar import ZERO_SERIAL_BELOW, fog_lidar_into

    n = 20_000
    clean = _cloud(3, n)
    level = parse_fog("dense")
    channel = np.full((2 * n + 30_000, 5), np.nan, np.float32)  # the tail alone is above the parallel threshold
    rows = fog_lidar_into(clean, level, np.random.default_rng(3), channel, "dual")
    assert (len(channel) - rows) * 5 >= ZERO_SERIAL_BELOW
    reference = apply_returns(clean, fog_lidar(clean, level, np.random.default_rng(3)), None, "dual",
                              alpha=level.alpha, capacity=len(channel))  # fmt: skip
    assert np.array_equal(channel, reference)


def test_writing_into_a_channel_refuses_a_wrong_one_before_any_work():
    from fog_gym.fog.lidar import fog_lidar_into

    clean = _cloud(0, 10)
    with pytest.raises(ValueError, match=r"^out must be a float32 array of the points' shape \(10, 4\)"):
        fog_lidar(clean, parse_fog("dense"), np.random.default_rng(0), out=np.zeros((10, 4)))
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match=r"^channel must be a C-contiguous float32 \(2 × 10 or more, 5\) point channel"):
        fog_lidar_into(clean, parse_fog("dense"), rng, np.zeros((15, 5), np.float32), "dual")
    with pytest.raises(ValueError, match=r"^channel must be a C-contiguous float32 \(10 or more, 4\) point channel"):
        fog_lidar_into(clean, parse_fog("dense"), rng, np.zeros((10, 5), np.float32), "last")
    with pytest.raises(ValueError, match=r"^channel must be a C-contiguous"):
        fog_lidar_into(clean, parse_fog("dense"), rng, np.zeros((20, 8), np.float32)[:, :4])
    with pytest.raises(ValueError, match=r"^columns must be a number of leading columns from 4 to 4"):
        fog_lidar_into(clean, parse_fog("dense"), rng, np.zeros((20, 3), np.float32), columns=3)
    with pytest.raises(ValueError, match="returns must be one of"):
        fog_lidar_into(clean, parse_fog("dense"), rng, np.zeros((20, 4), np.float32), "first")
    assert rng.uniform() == np.random.default_rng(0).uniform()  # no draw was taken
