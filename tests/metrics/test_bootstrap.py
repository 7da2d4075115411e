"""Paired bootstrap: cluster resampling, seed draws, intervals, and the weighted metrics it rests on (a frame drawn k
times counts k times: equal to evaluating the frames repeated)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.metrics.bootstrap import apply_draws, cluster_weights, interval, paired_differences, verdict


@settings(max_examples=50, deadline=None)
@given(st.lists(st.sampled_from("abcdef"), min_size=1, max_size=40), st.integers(1, 30), st.integers(0, 10**6))
def test_cluster_weights_draw_whole_clusters_as_many_times_as_there_are_clusters(labels, n, seed):
    w = cluster_weights(labels, n, seed)
    labels = np.array(labels)
    k = len(set(labels))
    assert w.shape == (n, len(labels)) and (w >= 0).all()
    for name in set(labels):
        cols = w[:, labels == name]
        assert (cols == cols[:, :1]).all()  # a cluster's items share their count
    per_cluster = np.stack([w[:, np.flatnonzero(labels == c)[0]] for c in sorted(set(labels))], 1)
    assert (per_cluster.sum(1) == k).all()  # k draws per resample


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="one label per item"):
        cluster_weights([], 10)
    with pytest.raises(ValueError, match="n must be a positive integer"):
        cluster_weights(["a"], 0)
    with pytest.raises(ValueError, match="level"):
        interval(0.0, np.zeros(3), level=1.5)


def test_interval_and_verdicts_of_known_samples():
    d = np.linspace(-1, 1, 2001)
    r = interval(0.0, d)
    assert r["lo"] == pytest.approx(-0.95) and r["hi"] == pytest.approx(0.95) and r["p_le0"] == pytest.approx(0.5, abs=1e-3)
    assert verdict(interval(0.5, d + 2)) == "better" and verdict(interval(-0.5, d - 2)) == "worse"
    assert verdict(r) == "not resolved" and verdict(interval(0.5, d + 2), higher_is_better=False) == "worse"
    assert math.isnan(interval(0.0, np.array([np.nan]))["lo"])


def test_seed_resampling_widens_the_interval_when_seeds_disagree():
    rng = np.random.default_rng(0)
    items = rng.normal(0, 0.01, (1, 500))
    agree = np.repeat(items, 3, 0)
    disagree = agree + np.array([[-0.3], [0.0], [0.3]])
    base = paired_differences(agree, np.zeros((3, 500)), 1)
    wide = paired_differences(disagree, np.zeros((3, 500)), 1)
    assert np.ptp(np.quantile(wide, [0.025, 0.975])) > 3 * np.ptp(np.quantile(base, [0.025, 0.975]))
    draws = np.array([[0, 0, 0], [2, 2, 1]])
    np.testing.assert_allclose(apply_draws(np.array([[1.0, 1.0], [2.0, 2.0], [4.0, 4.0]]), draws), [1.0, 10 / 3])


def _frames3d(rng, n_frames):
    gt, pr = [], []
    for _ in range(n_frames):
        n = rng.integers(0, 6)
        b = np.c_[rng.uniform(-20, 20, (n, 2)), rng.uniform(-1, 1, n), rng.uniform(3, 5, n), rng.uniform(1.5, 2, n),
                  rng.uniform(1.4, 3, n), rng.uniform(-3, 3, n)]  # fmt: skip
        c = rng.choice([0, 1, 4], n)
        m = rng.integers(0, 5)
        extra = np.c_[rng.uniform(-20, 20, (m, 2)), rng.uniform(-1, 1, m), rng.uniform(3, 5, m), rng.uniform(1.5, 2, m),
                      rng.uniform(1.4, 3, m), rng.uniform(-3, 3, m)]  # fmt: skip
        pb = np.r_[b + rng.normal(0, 0.3, b.shape) * [1, 1, 1, 0.1, 0.1, 0.1, 0.3], extra]
        pb[:, 3:6] = np.abs(pb[:, 3:6]) + 0.1
        gt.append({"boxes": b, "classes": c})
        pr.append({"boxes": pb, "classes": np.r_[c, rng.choice([0, 1, 4], m)], "scores": rng.random(n + m)})
    return gt, pr


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10**6))
def test_3d_metrics_of_weighted_frames_equal_those_of_repeated_frames(seed):
    from fog_gym.metrics.detection3d import evaluate, match_frames, summarise

    rng = np.random.default_rng(seed)
    gt, pr = _frames3d(rng, int(rng.integers(1, 8)))
    m = match_frames(gt, pr)
    plain = evaluate(gt, pr)
    once = summarise(m)
    for k in ("mAP", "ATE", "ASE", "AOE", "FDS"):
        assert once[k] == pytest.approx(plain[k], abs=1e-12, nan_ok=True)
    w = rng.integers(0, 3, len(gt))
    if w.sum() == 0:
        return
    rep = evaluate([g for g, k in zip(gt, w) for _ in range(k)], [p for p, k in zip(pr, w) for _ in range(k)])
    got = summarise(m, w)
    for k in ("mAP", "ATE", "ASE", "AOE", "FDS"):
        assert got[k] == pytest.approx(rep[k], abs=1e-12, nan_ok=True)
    many = summarise(m, np.stack([w, np.ones_like(w)]))  # rows at once equal rows one by one
    assert many["mAP"][0] == pytest.approx(got["mAP"], nan_ok=True) and many["mAP"][1] == pytest.approx(once["mAP"], nan_ok=True)


def _frames2d(rng, n_frames):
    gt, pr = [], []
    for _ in range(n_frames):
        n = rng.integers(0, 6)
        xy, wh = rng.uniform(0, 300, (n, 2)), rng.uniform(3, 60, (n, 2))
        b = np.c_[xy, xy + wh]
        c = rng.choice([0, 1, 4], n)
        m = rng.integers(0, 10)
        corners = rng.uniform(0, 300, (m, 4))
        extra = np.c_[np.minimum(corners[:, :2], corners[:, 2:]), np.maximum(corners[:, :2], corners[:, 2:])]
        pb = np.r_[np.clip(b + rng.normal(0, 3, b.shape), 0, None), extra].reshape(-1, 4)
        pb = np.c_[pb[:, :2], np.maximum(pb[:, 2:], pb[:, :2] + 0.5)]
        gt.append({"boxes": b, "classes": c, "ignore": rng.random(n) < 0.1})
        pr.append({"boxes": pb, "classes": np.r_[c, rng.choice([0, 1, 4], m)], "scores": rng.random(n + m)})
    return gt, pr


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10**6))
def test_coco_metrics_of_weighted_images_equal_pycocotools_on_repeated_images(seed):
    pytest.importorskip("pycocotools")
    from fog_gym.metrics.detection2d import coco_matches, coco_summarise, evaluate_coco

    rng = np.random.default_rng(seed)
    gt, pr = _frames2d(rng, int(rng.integers(1, 10)))
    m = coco_matches(gt, pr)
    plain, once = evaluate_coco(gt, pr), coco_summarise(m, thresholds=range(10))
    for k in ("mAP50", "mAP50_95", "precision", "recall"):
        assert once[k] == pytest.approx(plain[k], abs=1e-12, nan_ok=True)
    w = rng.integers(0, 3, len(gt))
    if w.sum() == 0:
        return
    rep = evaluate_coco([g for g, k in zip(gt, w) for _ in range(k)], [p for p, k in zip(pr, w) for _ in range(k)])
    got = coco_summarise(m, w, thresholds=range(10))
    for k in ("mAP50", "mAP50_95", "precision", "recall"):
        assert got[k] == pytest.approx(rep[k], abs=1e-12, nan_ok=True)
