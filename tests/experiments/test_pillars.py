"""Experiment 1's pillar detector: pillarisation against a slow reference, mirroring, the caps, the network's
shapes, decoding of encoded targets, and overfitting one sweep to mAP 1.0."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

torch = pytest.importorskip("torch")  # the torch extra is part of the dev extra: never skipped in CI

from fog_gym.experiments.detection3d.bev import BEVGrid, class_from_height, decode_cells, make_targets  # noqa: E402
from fog_gym.experiments.detection3d.data import mirror_boxes  # noqa: E402
from fog_gym.experiments.detection3d.model import decode, detection_loss  # noqa: E402
from fog_gym.experiments.detection3d.pillar_model import PillarCenterPoint, PillarConfig  # noqa: E402
from fog_gym.experiments.detection3d.pillars import mirror, pillar_points, pillarise  # noqa: E402
from fog_gym.metrics.detection3d import evaluate  # noqa: E402

SMALL = BEVGrid(range_m=4.0, cell_m=0.5, z_min=-2.0, z_max=1.0, stride=2)


def _cloud(seed: int, n: int, spread: float = 5.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    pts = np.c_[rng.uniform(-spread, spread, (n, 2)), rng.uniform(-2.5, 1.5, n), rng.uniform(0, 1, n)]
    # crowd a few pillars so that the point cap matters
    pts[: n // 3, :2] = rng.uniform(-0.49, -0.01, (n // 3, 2))
    return pts.astype(np.float32)


def _reference(points, grid):
    """Pillars by brute force: for every cell, the points inside it (as a set of rows)."""
    n = grid.shape[0]
    out = {}
    for p in points:
        i = int(np.floor((p[0] + grid.range_m) / grid.cell_m))
        j = int(np.floor((p[1] + grid.range_m) / grid.cell_m))
        if grid.z_min <= p[2] < grid.z_max and 0 <= i < n and 0 <= j < n:
            out.setdefault(i * n + j, []).append(tuple(p))
    return out


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 400), st.integers(1, 8))
def test_pillarisation_equals_a_slow_reference(seed, n, cap):
    pts = _cloud(seed, n)
    p = pillarise(pts, SMALL, seed=seed)
    ref = _reference(pts, SMALL)
    assert p.cells.tolist() == sorted(ref)  # every non-empty pillar once, ascending
    for k, cell in enumerate(p.cells):
        mine = p.points[p.starts[k]: p.starts[k] + p.counts[k]]
        assert sorted(map(tuple, mine)) == sorted(ref[cell])  # every point in its pillar, none elsewhere
    feats, pillar = pillar_points(p, SMALL, cap)
    assert (np.bincount(pillar, minlength=len(p.cells)) == np.minimum(p.counts, cap)).all()  # the cap
    n_cells = SMALL.shape[0]
    for k in np.unique(pillar):
        f = feats[pillar == k]
        kept = f[:, :3].astype(np.float64)
        np.testing.assert_allclose(f[:, 4:7], kept - kept.mean(axis=0), atol=2e-6)  # offsets to the mean
        cx = (p.cells[k] // n_cells + 0.5) * SMALL.cell_m - SMALL.range_m
        cy = (p.cells[k] % n_cells + 0.5) * SMALL.cell_m - SMALL.range_m
        np.testing.assert_allclose(f[:, 7], f[:, 0] - cx, atol=1e-6)  # offsets to the centre
        np.testing.assert_allclose(f[:, 8], f[:, 1] - cy, atol=1e-6)
        assert {tuple(r) for r in f[:, :4]} <= set(ref[p.cells[k]])  # a subset of the pillar's own points


def test_pillarisation_is_deterministic_and_a_seed_only_reorders_within_pillars():
    pts = _cloud(3, 500)
    a, b, c = pillarise(pts, SMALL, 1), pillarise(pts, SMALL, 1), pillarise(pts, SMALL, 2)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.cells, c.cells) and np.array_equal(a.counts, c.counts)
    assert not np.array_equal(a.points, c.points)
    assert sorted(map(tuple, a.points)) == sorted(map(tuple, c.points))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.booleans(), st.booleans())
def test_mirrored_pillars_are_the_pillars_of_the_mirrored_sweep(seed, flip_y, flip_x):
    pts = _cloud(seed, 300, spread=3.9)
    pts[:, :2] += 0.013  # keep points off the cell edges, where mirroring moves a point across one
    p = pillarise(pts, SMALL, seed)
    m = mirror(p, SMALL, flip_y, flip_x)
    sign = np.float32([-1 if flip_x else 1, -1 if flip_y else 1, 1, 1])
    ref = pillarise(pts * sign, SMALL, seed)
    assert np.array_equal(m.cells, ref.cells) and np.array_equal(m.counts, ref.counts)
    for k in range(len(m.cells)):
        a = m.points[m.starts[k]: m.starts[k] + m.counts[k]]
        b = ref.points[ref.starts[k]: ref.starts[k] + ref.counts[k]]
        assert sorted(map(tuple, a)) == sorted(map(tuple, b))


def test_mirrored_boxes_keep_their_corners_mirrored():
    from fog_gym.geometry import box_corners

    b = np.array([[3.0, -2.0, -1.0, 4.5, 1.9, 1.5, 0.4]])
    for fy, fx in ((True, False), (False, True), (True, True)):
        m = mirror_boxes(b, fy, fx)
        want = box_corners(b[:, :3], b[:, 3:6], b[:, 6])[0] * [-1 if fx else 1, -1 if fy else 1, 1]
        got = box_corners(m[:, :3], m[:, 3:6], m[:, 6])[0]
        assert sorted(map(tuple, want.round(9))) == sorted(map(tuple, got.round(9)))


def test_pillar_targets_decode_back_to_the_boxes():
    grid = PillarConfig().grid
    rng = np.random.default_rng(0)
    boxes = np.c_[rng.uniform(-39, 39, (40, 2)), rng.uniform(-1.5, -0.5, 40), rng.uniform(4, 9, 40),
                  rng.uniform(1.8, 2.6, 40), rng.uniform(1.4, 3.8, 40), rng.uniform(-np.pi, np.pi, 40)]  # fmt: skip
    cells = np.floor((boxes[:, :2] + 40) / grid.out_cell_m)
    boxes = boxes[np.unique(cells, axis=0, return_index=True)[1]]
    t = make_targets(boxes, class_from_height(boxes[:, 5]), grid)
    np.testing.assert_allclose(decode_cells(t["index"], t["regression"], grid), boxes, atol=1e-5)


@pytest.mark.parametrize("bad, match", [
    ({"widths": (32, -1, 128)}, "widths must be three positive integers"),
    ({"cell_m": 0.3}, "must be an integer multiple of stride|multiple of 4"),
    ({"range_m": 40.0, "cell_m": 0.8}, "multiple of 4"),
    ({"max_points": 0}, "max_points must be a positive integer"),
])  # fmt: skip
def test_bad_pillar_configs_are_one_line_errors(bad, match):
    with pytest.raises(ValueError, match=match) as e:
        PillarConfig(**bad)
    assert "\n" not in str(e.value)


def test_the_network_overfits_one_sweep_to_map_one():
    """A tiny pillar network learns one synthetic sweep of three vehicles to mAP@0.5 = 1 in a few hundred steps."""
    cfg = PillarConfig(range_m=12.8, cell_m=0.4, widths=(16, 16, 32), layers=(1, 2, 2), pfn=16, up=16, head=16)
    grid = cfg.grid
    boxes = np.array([[5.0, 2.0, -1.25, 4.5, 1.9, 1.5, 0.3], [-6.0, -4.0, -0.9, 5.2, 2.1, 2.2, -1.2],
                      [2.0, -7.0, -0.2, 8.0, 2.5, 3.6, 1.6]])  # fmt: skip
    rng = np.random.default_rng(0)
    pts = []
    for b in boxes:  # points on each box's surface
        u = rng.uniform(-0.5, 0.5, (600, 3))
        face = rng.integers(0, 3, 600)
        u[np.arange(600), face] = np.sign(u[np.arange(600), face]) * 0.5
        c, s = np.cos(b[6]), np.sin(b[6])
        local = u * b[3:6]
        pts.append(np.c_[b[0] + local[:, 0] * c - local[:, 1] * s, b[1] + local[:, 0] * s + local[:, 1] * c,
                         b[2] + local[:, 2], np.full(600, 0.6)])  # fmt: skip
    ground = np.c_[rng.uniform(-12.8, 12.8, (3000, 2)), np.full(3000, -2.0), np.full(3000, 0.2)]
    sweep = np.concatenate(pts + [ground]).astype(np.float32)
    classes = class_from_height(boxes[:, 5])
    p = pillarise(sweep, grid)
    feats, pillar = pillar_points(p, grid, 32)
    t = make_targets(boxes, classes, grid)
    torch.manual_seed(0)
    net = PillarCenterPoint(cfg)
    opt = torch.optim.Adam(net.parameters(), 3e-3)
    inputs = {"feats": torch.from_numpy(feats), "pillar": torch.from_numpy(pillar), "cells": torch.from_numpy(p.cells),
              "batch": torch.zeros(len(p.cells), dtype=torch.long), "batch_size": 1}  # fmt: skip
    heat = torch.from_numpy(t["heatmap"])[None]
    args = (torch.zeros(len(boxes), dtype=torch.long), torch.from_numpy(t["index"]), torch.from_numpy(t["regression"]))
    best = 0.0
    for step in range(300):
        net.train()
        loss, _ = detection_loss(net(**inputs), heat, *args, reg_weight=1.0)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % 50 == 49:
            net.eval()
            with torch.no_grad():
                pred = decode(net(**inputs), grid, threshold=0.3)
            best = evaluate([{"boxes": boxes, "classes": classes}], pred)["mAP"]
            if best == 1.0:
                break
    assert best == 1.0
