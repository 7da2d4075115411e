#!/usr/bin/env bash
# One prepared run on a lent GPU machine (an H200 with 16 CPU cores, ~10 minutes): Experiment 1's GPU configuration
# (--gpu) on the study's data (168 scenes, LiDAR only, generated there with 16 workers), then the scaling of
# `fog-gym generate` and the sharded vector env over 1 … 16 cores. Results land in $OUT (at most 8 files).
#
#   bash scripts/device_run.sh            # on the device machine, from the repository root (.whl carried)
#
# The machine lacks gymnasium, highway-env and pygame-ce: their wheels travel in .whl/ (README's device notes);
# imagecodecs (26 MB) does not fit the transfer, so its one function used here (zlib-ng's encoder) is stood in
# for by stock zlib, which only changes how fast PNGs compress. Each part has a deadline, so that what finished
# comes back even when a later part does not. Sizes are environment variables, so a toy run can check the script
# on a CPU first: SCENES=4 SECONDS_=2 GEN_WORKERS=2 EXP1_FLAGS="--epochs 1 ..." bash scripts/device_run.sh
set -u
export PYTHONUNBUFFERED=1
OUT=${OUT:-out/device}
SCENES=${SCENES:-168}
SECONDS_=${SECONDS_:-10}
GEN_WORKERS=${GEN_WORKERS:-16}
BUDGET=${BUDGET:-580}
EXP1_FLAGS=${EXP1_FLAGS:---gpu --epochs 20 --batch-size 16 --every 1 --test-every 4 --eval-every 5 --workers 8}
WORK=${WORK:-/tmp/fog_gym_device}
mkdir -p "$OUT" "$WORK" /tmp/site
left() { echo $((BUDGET - SECONDS - ${1:-0})); }

if [ -z "${NO_WHL:-}" ] && ls .whl/*.whl > /dev/null 2>&1; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
fi
python3 -c "import imagecodecs" 2> /dev/null || printf '%s\n' 'import zlib' 'import numpy as np' '' \
  'def zlibng_encode(data, level=1):' '    return zlib.compress(np.ascontiguousarray(data).tobytes(), level)' \
  > /tmp/site/imagecodecs.py
export PYTHONPATH=/tmp/site:$PWD${PYTHONPATH:+:$PYTHONPATH}
fg() { python3 -c 'import sys; from fog_gym.cli import main; sys.exit(main())' "$@"; }
{
  date -u; nproc; lscpu | grep -E "Model name"; nvidia-smi -L 2>&1
  python3 -c "import torch, numpy, numba; print('torch', torch.__version__, 'numpy', numpy.__version__, 'numba', numba.__version__, 'cuda', torch.cuda.is_available())"
  python3 -c "import fog_gym._numba as n; print('numba threading layer', n.threading_layer())"  # TBB where its wheel loads
} > "$OUT/machine.txt" 2>&1

# 1. the study's data: the documented command, with 16 workers
t=$SECONDS
timeout "$(left 300)" python3 -c 'import sys; from fog_gym.cli import main; sys.exit(main())' generate \
  --root "$WORK/lidar" --scenes "$SCENES" --seconds "$SECONDS_" --lidar-only --workers "$GEN_WORKERS" \
  > "$OUT/generate.log" 2>&1
echo "generate: rc=$? $((SECONDS - t)) s" | tee -a "$OUT/machine.txt"

# 2. Experiment 1, GPU configuration, the pillar detector's Light row at seed 0
if [ -f "$WORK/lidar/index/splits.json" ]; then
  t=$SECONDS
  # shellcheck disable=SC2086
  timeout "$(left 130)" python3 -c 'import sys; from fog_gym.cli import main; sys.exit(main())' exp1 \
    --root "$WORK/lidar" --out "$WORK/exp1_gpu" --detectors pillars --rows Light --seeds 1 $EXP1_FLAGS \
    > "$OUT/exp1.log" 2>&1
  echo "exp1: rc=$? $((SECONDS - t)) s" | tee -a "$OUT/machine.txt"
  cp "$WORK/exp1_gpu/exp1.md" "$OUT/exp1_gpu.md" 2> /dev/null
  python3 - "$WORK/exp1_gpu" "$OUT/exp1_gpu_curve.json" <<'EOF' >> "$OUT/machine.txt" 2>&1
import json, sys
from pathlib import Path
import torch
out, dest = Path(sys.argv[1]), Path(sys.argv[2])
rows = sorted((out / "rows").glob("*.json"))
if rows:  # the finished unit: its record (best-FDS cells, learning curve, wall time)
    dest.write_text(json.dumps([json.loads(p.read_text()) for p in rows]))
else:  # cut short: the learning curve so far, from the last epoch's checkpoint
    for p in sorted((out / "checkpoints").glob("*.pt")):
        state = torch.load(p, map_location="cpu", weights_only=False)
        dest.write_text(json.dumps({"unfinished": p.stem, "state": {k: v for k, v in state.items() if k in ("curve", "best", "epoch", "step", "seconds")}}, default=str))
print("exp1 record:", dest.exists())
EOF
fi

# 3. scaling over cores: generate (16 scenes x 1 s, full rig, 640 x 480) and the sharded vector env
t=$SECONDS
timeout "$(left 5)" python3 -m fog_gym.experiments.bench.speed --quick --no-figures --json "$OUT/scaling.json" \
  > "$OUT/scaling.log" 2>&1
echo "scaling: rc=$? $((SECONDS - t)) s" | tee -a "$OUT/machine.txt"
