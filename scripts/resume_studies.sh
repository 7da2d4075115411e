#!/usr/bin/env bash
# Resume Experiments 1 and 2 on a fresh machine from the units kept in the repository (results/exp1, results/exp2).
#
#   bash scripts/resume_studies.sh [exp1|exp2|both] [-- EXTRA RUNNER FLAGS]
#
# The data and the runs' working folders may not outlive a machine; the kept units do (commit results/ as they land).
# For each study this generates its data with the documented command unless its done-marker exists (resuming a
# cut one; Experiment 1: 168 LiDAR-only scenes, 12-13 minutes on two cores; Experiment 2: 160 two-camera scenes
# at 640 x 480, 7-11 minutes, 14 GB), then runs the whole study with --keep: units kept before are restored, not
# rerun, and each unit finished now is copied into results/ at once. Kill it at any point; run it again to go on.
# If the regenerated data's digest differs from the study record's (the same scenes generated on another CPU can
# differ in floating-point last bits), the runner refuses and names the digest: check it, then pass
# `-- --accept-data sha256:...` with that study alone (flags after -- go to each study run). Run from the
# repository root. Logs: $RUNS/exp1.log and $RUNS/exp2.log (docs/experiments/runner.md).
#
# Environment: DATA (default out/data) holds the datasets, RUNS (default out/runs) the runs' working folders;
# FOG_GYM (default: fog-gym on PATH, else .venv/bin/fog-gym) the command.
set -euo pipefail
case "${1:-both}" in
  -h|--help) sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  exp1|exp2|both) WHICH=${1:-both}; shift $(( $# > 0 ? 1 : 0 )) ;;
  *) echo "resume_studies.sh: unknown study '$1' (choose exp1, exp2 or both; --help)" >&2; exit 2 ;;
esac
[ "${1:-}" = "--" ] && shift
if [ "$WHICH" = both ] && [ $# -gt 0 ]; then
  echo "resume_studies.sh: runner flags go to one study (exp1 or exp2)" >&2; exit 2
fi
[ -d results ] && [ -f pyproject.toml ] || { echo "resume_studies.sh: run it from the repository root" >&2; exit 2; }
DATA=${DATA:-out/data}
RUNS=${RUNS:-out/runs}
FOG_GYM=${FOG_GYM:-$(command -v fog-gym || echo .venv/bin/fog-gym)}
if [ ! -x "$FOG_GYM" ]; then
  echo "resume_studies.sh: no fog-gym command (run ./dev demo first, or set FOG_GYM)" >&2; exit 2
fi
mkdir -p "$DATA" "$RUNS"

generate() {  # generate ROOT ARGS...: the dataset once (an interrupted one resumed); the marker says it finished
  local root=$1; shift
  if [ ! -f "$root.done" ]; then
    "$FOG_GYM" generate --root "$root" "$@" --workers 2 $([ -d "$root" ] && echo --resume) \
      && touch "$root.done"
  fi
}

if [ "$WHICH" != exp2 ]; then
  generate "$DATA/lidar168" --scenes 168 --seconds 10 --lidar-only
  "$FOG_GYM" exp1 --root "$DATA/lidar168" --out "$RUNS/exp1" --keep results/exp1 --seeds 3 --budget-epochs 3 20 \
    "$@" 2>&1 | tee -a "$RUNS/exp1.log"
fi
if [ "$WHICH" != exp1 ]; then
  generate "$DATA/cam160" --scenes 160 --seconds 10 --resolution 640x480 --modality cameras \
    --cameras CAM_FRONT CAM_LEFT
  for seeds in 1 2 3; do  # one seed's whole report (its evaluation too) before the next seed's training
    "$FOG_GYM" exp2 --root "$DATA/cam160" --out "$RUNS/exp2" --keep results/exp2 --seeds "$seeds" "$@" 2>&1 \
      | tee -a "$RUNS/exp2.log"
  done
fi
