"""Fuzzing the readers: ``validate``, the ``FogDrive`` access class and the torch loader over corrupted files.

One file of a small valid set is corrupted at a time (bit flips, header flips, truncation, random bytes, spliced
bytes, ``.npy`` files of the wrong dtype/shape/order or with NaN, PNGs of the wrong kind or size, JSON values of the
wrong type, JSON bombs), then:

* data files (PNG, ``.npy``, box JSON): ``validate``'s check of that file and the torch loader's decoding of it
  never raise anything but the loader's ``DatasetError`` naming the file; a file ``validate`` accepts loads, and
  a file the loader refuses is one ``validate`` reports;
* index and metadata files (the index tables, splits, manifest, layout, extrinsics, ego poses): the whole of
  ``validate``, the access class (every sample's paths and ego pose, every scene's extrinsics, every split) and the
  torch loader over every sample run; ``validate`` never raises and names a file in every problem line; the access
  class and the loader raise only ``DatasetError``/``FileNotFoundError`` naming a file, and only where ``validate``
  reports a problem.

Every example runs under an alarm (a hang fails the test). The default run does a few thousand examples; the slow
run (``-m slow``) over 10⁵.
"""

from __future__ import annotations

import io
import json
import re
import shutil
import signal
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest

torch = pytest.importorskip("torch")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from fog_gym.dataset import FogDrive  # noqa: E402
from fog_gym.dataset.access import DatasetError  # noqa: E402
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS, LAYOUT_FILE, layout_to_json  # noqa: E402
from fog_gym.dataset.manifest import read_manifest  # noqa: E402
from fog_gym.dataset.torch import FogDriveDataset  # noqa: E402
from fog_gym.dataset.validate import _check_file, validate  # noqa: E402
from fog_gym.generate import generate, plan_scenes  # noqa: E402

HANG_S = 30  # an example slower than this is a hang
NAMED = re.compile(r"^[^:]*(/|\.\w+)[^:]*: ")  # "<file name>: <problem>"
JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**70), 2**70) | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4), max_leaves=12,
)  # fmt: skip
BOMBS = [b"[" * 100_000, b"9" * 5000, b"1e999", b"NaN", b"[[[[]]]]", b'{"a": ' * 5000, b"\xff\xfe", b"", b"{}", b"[]"]


class Alarm:
    def __enter__(self):
        def hang(signum, frame):
            raise TimeoutError(f"an example took over {HANG_S} s: a hang")

        self.old = signal.signal(signal.SIGALRM, hang)
        signal.alarm(HANG_S)

    def __exit__(self, *exc):
        signal.alarm(0)
        signal.signal(signal.SIGALRM, self.old)


class Harness:
    """A pristine set, its files by kind, and the checks of one corrupted file."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.ds = FogDrive(root)
        self.size = tuple(read_manifest(root)["resolution"])
        self.records = list(self.ds.sample_data)
        self.position = {s["token"]: i for i, s in enumerate(self.ds.sample)}
        self.loaders = {c: FogDriveDataset(root, channels=[c]) for c in self.ds.list_channels()}
        self.meta = sorted([*(root / "index").glob("*.json"), *root.glob("data_root/*/extrinsic_config/*.json"),
                            *root.glob("data_root/*/ego_pose/*.json")])  # fmt: skip
        self.original = {p: p.read_bytes() for p in [*self.meta, *(root / r["filename"] for r in self.records)]}
        self.outcomes: Counter = Counter()

    # -- data files ---------------------------------------------------------------------------------------------
    def check_data(self, rec: dict, data: bytes) -> None:
        path = self.root / rec["filename"]
        path.write_bytes(data)
        try:
            with Alarm():
                problem = _check_file(self.root, rec, self.size, self.ds.channels)  # what validate runs on it
                try:
                    self.loaders[rec["channel"]][self.position[rec["sample_token"]]]
                    loaded = True
                except DatasetError as e:
                    assert rec["filename"] in str(e), f"the loader's error does not name the file: {e}"
                    loaded = False
            assert loaded or problem is not None, f"the loader refused {rec['filename']}, validate did not"
            # the loader is as strict as validate, but for PNGs: it converts any decodable image, of any size
            assert problem is None or not loaded or rec["fileformat"] == "png", f"{problem}, yet it loads"
            self.outcomes["data: " + ("valid" if problem is None else "reported") + (", loads" if loaded else "")] += 1
        finally:
            path.write_bytes(self.original[path])

    # -- index and metadata files -------------------------------------------------------------------------------
    def check_meta(self, path: Path, data: bytes) -> None:
        path.write_bytes(data)
        try:
            with Alarm():
                problems = validate(self.root)
                for line in problems:  # a path of the set, or the file name an index entry gives
                    assert str(self.root) in line or NAMED.match(line), f"names no file: {line}"
                failures = [self._access(), self._loader()]
            failures = [f for f in failures if f is not None]
            for f in failures:
                assert str(self.root) in f, f"the error names no file: {f}"
            assert problems or not failures, f"validate found nothing, but: {failures}"
            self.outcomes["meta: " + ("reported" if problems else "valid") + (", refused" if failures else "")] += 1
        finally:
            path.write_bytes(self.original[path])

    def _access(self) -> str | None:
        try:
            ds = FogDrive(self.root)
            for s in ds.sample:
                ds.get_sample_paths(s["token"])
                ds.get_ego_pose(s["token"])
                ds.get_scene_for_sample(s["token"])
            for sc in ds.scene:
                ds.load_extrinsic_config(sc["token"])
                ds.get_samples_for_scene(sc["token"])
            for split in ("train", "val", "test"):
                ds.get_sample_tokens_for_split(split)
        except (DatasetError, FileNotFoundError) as e:
            return str(e)
        return None

    def _loader(self) -> str | None:
        try:
            d = FogDriveDataset(self.root, split="train")
            for i in range(len(d)):
                d[i]
        except (DatasetError, FileNotFoundError) as e:
            return str(e)
        return None


# -- mutations -------------------------------------------------------------------------------------------------
def _flip(data: bytes, flips: list[tuple[int, int]], head: bool) -> bytes:
    b = bytearray(data)
    if not b:
        return bytes(b)
    for pos, bit in flips:
        b[pos % (min(len(b), 128) if head else len(b))] ^= 1 << bit
    return bytes(b)


def _npy(kind: int, n: int) -> bytes:
    arrays = [np.zeros((n, 4)), np.zeros((n, 4), np.float16), np.zeros((n, 4), np.int32), np.zeros(n, np.float32),
              np.zeros((n, 3), np.float32), np.zeros((n, 7), np.float32), np.zeros((2, n, 4), np.float32),
              np.zeros((), np.float32), np.full((n, 4), np.nan, np.float32), np.zeros((n, 4), ">f4"),
              np.asfortranarray(np.zeros((max(n, 2), 4), np.float32)), np.zeros((n, 6), np.float32),
              np.zeros((n, 4), bool), np.zeros((n, 4), np.complex64), np.full((n, 4), np.inf, np.float32)]  # fmt: skip
    buf = io.BytesIO()
    np.save(buf, arrays[kind % len(arrays)])
    return buf.getvalue()


def _png(kind: int, size: tuple[int, int]) -> bytes:
    w, h = size
    images = [np.zeros((h, w), np.uint8), np.zeros((h, w, 4), np.uint8), np.zeros((h, w, 3), np.uint16),
              np.zeros((h + 1, w, 3), np.uint8), np.zeros((1, 1, 3), np.uint8), np.zeros((h, w * 2, 3), np.uint8)]  # fmt: skip
    return cv2.imencode(".png", images[kind % len(images)])[1].tobytes()


def _json_retype(data: bytes, path: list[int], value) -> bytes:
    try:
        doc = json.loads(data)
    except ValueError:
        return json.dumps(value).encode()
    node, parent, key = doc, None, None
    for step in path:
        if isinstance(node, dict) and node:
            parent, key = node, list(node)[step % len(node)]
        elif isinstance(node, list) and node:
            parent, key = node, step % len(node)
        else:
            break
        node = parent[key]
    if parent is None:
        return json.dumps(value).encode()
    parent[key] = value
    return json.dumps(doc).encode()


def mutation(suffix: str, size: tuple[int, int]):
    """A strategy of functions corrupting the bytes of a file with this suffix."""
    common = [
        st.lists(st.tuples(st.integers(0, 2**40), st.integers(0, 7)), min_size=1, max_size=8).map(
            lambda f: lambda d: _flip(d, f, head=False)),
        st.lists(st.tuples(st.integers(0, 2**40), st.integers(0, 7)), min_size=1, max_size=4).map(
            lambda f: lambda d: _flip(d, f, head=True)),
        st.integers(0, 2**40).map(lambda n: lambda d: d[: n % max(len(d), 1)]),
        st.binary(max_size=600).map(lambda r: lambda d: r),
        st.tuples(st.integers(0, 2**40), st.binary(min_size=1, max_size=64)).map(
            lambda t: lambda d: d[: t[0] % max(len(d), 1)] + t[1] + d[t[0] % max(len(d), 1) + len(t[1]):]),
    ]  # fmt: skip
    if suffix == ".npy":
        common.append(st.tuples(st.integers(0, 100), st.integers(0, 50)).map(lambda t: lambda d: _npy(*t)))
    elif suffix == ".png":
        common.append(st.integers(0, 100).map(lambda k: lambda d: _png(k, size)))
    else:
        common.append(st.tuples(st.lists(st.integers(0, 2**20), max_size=6), JSON_VALUES).map(
            lambda t: lambda d: _json_retype(d, *t)))  # fmt: skip
        common.append(st.sampled_from(BOMBS).map(lambda b: lambda d: b))
    return st.one_of(common)


# -- the tests ---------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def harness(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz") / "set"
    generate(root, plan_scenes(2, towns=("merge",), seed=6, resolution=(24, 16), seconds=0.1), progress=False)
    (root / LAYOUT_FILE).write_text(json.dumps(layout_to_json(FOGDRIVE_CHANNELS)))  # fuzz the layout file too
    assert validate(root) == []
    h = Harness(root)
    yield h
    shutil.rmtree(root, ignore_errors=True)


def _run(harness: Harness, data_examples: int, meta_examples: int, derandomize: bool) -> Counter:
    common = dict(deadline=None, database=None, derandomize=derandomize,
                  suppress_health_check=list(HealthCheck))  # fmt: skip

    @settings(max_examples=data_examples, **common)
    @given(st.data())
    def data_files(draw):
        rec = draw.draw(st.sampled_from(harness.records))
        corrupt = draw.draw(mutation(Path(rec["filename"]).suffix, harness.size))
        harness.check_data(rec, corrupt(harness.original[harness.root / rec["filename"]]))

    @settings(max_examples=meta_examples, **common)
    @given(st.data())
    def meta_files(draw):
        path = draw.draw(st.sampled_from(harness.meta))
        corrupt = draw.draw(mutation(path.suffix, harness.size))
        harness.check_meta(path, corrupt(harness.original[path]))

    harness.outcomes.clear()
    data_files()
    meta_files()
    assert validate(harness.root) == []  # every file was restored
    return harness.outcomes


def test_readers_survive_corrupted_files(harness):
    outcomes = _run(harness, 1500, 300, derandomize=True)
    assert sum(outcomes.values()) >= 1800
    assert any(k.startswith("data: reported") for k in outcomes) and any(k.startswith("meta: reported") for k in outcomes)


@pytest.mark.slow
def test_readers_survive_over_100k_corrupted_files(harness):
    outcomes = _run(harness, 88_000, 12_500, derandomize=False)
    print(f"\nfuzz: {sum(outcomes.values())} corrupted files: {dict(sorted(outcomes.items()))}")
    assert sum(outcomes.values()) >= 100_000
