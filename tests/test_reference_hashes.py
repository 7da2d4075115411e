"""Refactors keep behaviour: fixed seeds give byte-identical observations, labels and datasets.

The reference digests in ``tests/reference_hashes.json`` were recorded before the structure work of the
sensor/fog/world refactor. Images, point clouds and ids are compared bit for bit; float64 label values (the
``info`` boxes, the JSON box files) at 9 significant digits, because numpy's SIMD kernels for ``sin``/``cos``
differ in the last bit between CPUs (AVX-512 or not: ``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL"`` reproduces
the other machines' values). A change that alters any of them changes what users get for the same seed; if
that is intended (a physics fix, a new default), re-record with ``python -m tests.test_reference_hashes
--record`` and say why in the commit.
"""

from __future__ import annotations

import hashlib
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

REFERENCE = Path(__file__).with_name("reference_hashes.json")
# (town, time of day, traffic core, fog levels, seed): both traffic cores, day and night, fog and clear
CASES = [
    ("highway", "day", "fast", ("light", "moderate", "dense"), 3),
    ("merge", "day", "reference", ("dense",), 5),
    ("intersection", "night", "fast", (), 0),
]
RESOLUTION = (48, 36)
STEPS = 2


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


SIGNIFICANT = 9  # float64 labels are compared to this many significant digits (module docstring)


def _float(v: float) -> str:
    return f"{float(v):.{SIGNIFICANT}g}"


def _plain(v: Any) -> Any:
    """JSON-able form of labels: float64 values as text at :data:`SIGNIFICANT` digits, other arrays as digests."""
    if isinstance(v, np.ndarray):
        if v.dtype == np.float64:
            return {"shape": list(v.shape), "values": [_float(x) for x in v.ravel()]}
        return {"dtype": str(v.dtype), "shape": list(v.shape), "sha": _digest(np.ascontiguousarray(v).tobytes())}
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in sorted(v.items(), key=lambda kv: str(kv[0]))}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, (np.floating, float)):
        return _float(v)
    if isinstance(v, np.integer):
        return int(v)
    return v if isinstance(v, (str, int, bool, type(None))) else repr(v)


def _labels_digest(info: dict[str, Any]) -> str:
    """Digest of the label part of ``info`` (boxes and every other key)."""
    return _digest(json.dumps(_plain(info), sort_keys=True).encode())


def _file_digest(path: Path) -> str:
    """A file's digest: JSON files by their content with floats at :data:`SIGNIFICANT` digits, others bytewise."""
    if path.suffix == ".json":
        return _digest(json.dumps(_plain(json.loads(path.read_text())), sort_keys=True).encode())
    return _digest(path.read_bytes())


def env_hashes(town: str, time_of_day: str, traffic: str, fog: tuple[str, ...], seed: int) -> dict[str, str]:
    """Per-channel digests of the observation and the label ``info`` after each of ``STEPS`` idle steps."""
    import gymnasium as gym

    import fog_gym  # noqa: F401  (registers the ids)

    kwargs: dict[str, Any] = dict(town=town, time_of_day=time_of_day, traffic=traffic, resolution=RESOLUTION)
    if fog:
        kwargs["fog"] = list(fog)
    env = gym.make("FogDrive-v0", **kwargs)
    obs, info = env.reset(seed=seed)
    out = {}
    for step in range(STEPS + 1):
        if step:
            obs, _, _, _, info = env.step(env.unwrapped.idle_action)
        for key in sorted(obs):
            out[f"{step}/{key}"] = _digest(np.ascontiguousarray(obs[key]).tobytes())
        out[f"{step}/info"] = _labels_digest(info)
    env.close()
    return out


def dataset_hashes() -> dict[str, str]:
    """Digest of every file of a two-scene generated set (index tables included)."""
    from fog_gym.generate import generate, plan_scenes

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "set"
        generate(root, plan_scenes(2, towns=("roundabout",), seed=11, resolution=(32, 24), seconds=0.2),
                 workers=1, progress=False)  # fmt: skip
        return {str(p.relative_to(root)): _file_digest(p) for p in sorted(root.rglob("*")) if p.is_file()}


def all_hashes() -> dict[str, dict[str, str]]:
    out = {"/".join(map(str, (t, d, tr, "+".join(f) or "clear", s))): env_hashes(t, d, tr, f, s) for t, d, tr, f, s in CASES}
    out["dataset"] = dataset_hashes()
    return out


@pytest.fixture(scope="module")
def reference() -> dict[str, dict[str, str]]:
    return json.loads(REFERENCE.read_text())


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c[0]}-{c[1]}-{c[2]}-{len(c[3])}fog")
def test_observations_and_labels_are_byte_identical_to_the_reference(case, reference):
    key = "/".join(map(str, (case[0], case[1], case[2], "+".join(case[3]) or "clear", case[4])))
    got = env_hashes(*case)
    changed = sorted(k for k in reference[key] if got.get(k) != reference[key][k])
    assert set(got) == set(reference[key]), "the observation keys changed"
    assert changed == [], f"{key}: these channels changed for the same seed: {changed}"


def test_a_generated_dataset_is_byte_identical_to_the_reference(reference):
    got = dataset_hashes()
    assert sorted(got) == sorted(reference["dataset"]), "the set's file list changed"
    changed = sorted(k for k in got if got[k] != reference["dataset"][k])
    assert changed == [], f"these files changed for the same seed: {changed}"


if __name__ == "__main__":
    if sys.argv[1:] != ["--record"]:
        sys.exit("usage: python -m tests.test_reference_hashes --record")
    REFERENCE.write_text(json.dumps(all_hashes(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {REFERENCE}")
