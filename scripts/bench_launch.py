"""What a parallel kernel launch costs on each of numba's threading layers here, each layer in a child process.

Per layer that loads (``tbb``, ``workqueue``, ``omp``): a ``prange`` over two chunks that writes ``sqrt(x)·2`` into an
array of 10, 100 000 and 1 000 000 elements, against the same loop compiled without ``parallel``; median and least of
``--calls`` calls, the two kernels alternating. The smallest size is the launch alone: waking the other cores' workers
and waiting for them. ``fog_gym._numba`` picks TBB where it loads, else workqueue (``docs/performance.md``, "The
threading layer").

Run: python scripts/bench_launch.py [--calls 50] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

CHILD = r"""
import json, sys, time
import numpy as np
import fog_gym._numba  # loads TBB's library by its path (NUMBA_THREADING_LAYER names the layer)
import numba
from numba import njit, prange

@njit(parallel=True, nogil=True)
def parallel(x, out):
    n = x.shape[0]
    for c in prange(2):
        for i in range(c * n // 2, (c + 1) * n // 2):
            out[i] = np.sqrt(x[i]) * 2.0

@njit(nogil=True)
def serial(x, out):
    for i in range(x.shape[0]):
        out[i] = np.sqrt(x[i]) * 2.0

calls = int(sys.argv[1])
rows = {}
for n in (10, 100_000, 1_000_000):
    x = np.random.default_rng(0).random(n)
    out = np.empty_like(x)
    parallel(x, out), serial(x, out)
    ts, tp = [], []
    for _ in range(calls):
        t = time.perf_counter(); serial(x, out); ts.append(time.perf_counter() - t)
        t = time.perf_counter(); parallel(x, out); tp.append(time.perf_counter() - t)
    rows[n] = {"serial_us": float(np.median(ts)) * 1e6, "parallel_us": float(np.median(tp)) * 1e6,
               "parallel_min_us": min(tp) * 1e6}
print(json.dumps({"layer": numba.threading_layer(), "threads": numba.get_num_threads(), "rows": rows}))
"""


def measure(layer: str, calls: int) -> dict | None:
    """The child's figures on ``layer``, or None where the layer does not load here."""
    env = {**os.environ, "NUMBA_THREADING_LAYER": layer}
    out = subprocess.run([sys.executable, "-c", CHILD, str(calls)], env=env, capture_output=True, text=True,
                         check=False)  # fmt: skip
    if out.returncode:
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    from pathlib import Path

    from tqdm import tqdm

    from fog_gym.experiments.bench.common import markdown_table, positive_int, write_json

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=positive_int, default=50, help="timed calls per kernel and size (default 50)")
    ap.add_argument("--json", type=Path, help="also write the figures as JSON to this path")
    args = ap.parse_args(argv)
    results = {layer: measure(layer, args.calls) for layer in tqdm(("tbb", "workqueue", "omp"), desc="layers",
                                                                     unit="layer")}  # fmt: skip
    rows = []
    for layer, r in results.items():
        if r is None:
            rows.append([layer, "does not load here", "", "", ""])
            continue
        cells = [f"{v['parallel_us']:.0f} ({v['parallel_min_us']:.0f})" for v in r["rows"].values()]
        serial = " / ".join(f"{v['serial_us']:.0f}" for v in r["rows"].values())
        rows.append([f"{layer} ({r['threads']} threads)", *cells, serial])
    print(f"**Parallel launches** (median of {args.calls} calls, least in brackets; µs)")
    header = ["layer", "10 elements (the launch)", "100 000", "1 000 000", "serial: 10 / 100 000 / 1 000 000"]
    print(markdown_table(header, rows))
    write_json(args.json, results)
    return 0

if __name__ == "__main__":
    raise SystemExit(main())
