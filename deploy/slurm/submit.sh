#!/usr/bin/env bash
# Submits a wgslam batch to Slurm: a job array with one task per manifest job
# (wgslam-array.sbatch) and, after it, the collect job (wgslam-collect.sbatch, queued with
# --dependency=afterany so it also runs when some tasks failed).
#
# Usage: deploy/slurm/submit.sh MANIFEST OUT [sbatch options for the array...]
#   e.g. deploy/slurm/submit.sh runs/icl.toml /shared/out/icl --partition=gpu --gres=gpu:1
#        deploy/slurm/submit.sh runs/big.toml /shared/out/big --array=0-15   # 16 shards
# Prints "array job ID (N tasks)" and "collect job ID"; task logs go to OUT/slurm-logs/.
# Environment: WGSLAM_BIN, the binary every node can run [wgslam on PATH]; WGSLAM_VK_ICD
# (see wgslam-array.sbatch). MANIFEST, OUT and the binary must be on a filesystem every
# node sees.
set -euo pipefail

if (($# < 2)); then
  echo "usage: $0 MANIFEST OUT [sbatch options for the array...]" >&2
  exit 2
fi
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
MANIFEST=$(realpath "$1")
mkdir -p "$2/slurm-logs"
OUT=$(realpath "$2")
shift 2
WGSLAM_BIN=${WGSLAM_BIN:-wgslam}
command -v "$WGSLAM_BIN" >/dev/null || {
  echo "submit.sh: no wgslam binary '$WGSLAM_BIN' (set WGSLAM_BIN)" >&2
  exit 2
}
WGSLAM_BIN=$(realpath "$(command -v "$WGSLAM_BIN")")

# `wgslam batch list` ends with "N jobs"; it also checks the manifest before anything is queued.
N=$("$WGSLAM_BIN" batch list "$MANIFEST" | awk '/^[0-9]+ jobs?( |$)/ { print $1 }')
if [[ -z $N || $N -lt 1 ]]; then
  echo "submit.sh: $MANIFEST has no jobs" >&2
  exit 1
fi
array_opt=(--array="0-$((N - 1))")
for a in "$@"; do
  [[ $a == --array=* || $a == -a* ]] && array_opt=() # the caller sizes the array
done

export MANIFEST OUT WGSLAM_BIN
array=$(sbatch --parsable "${array_opt[@]}" --output="$OUT/slurm-logs/batch-%A_%a.out" \
  "$@" "$HERE/wgslam-array.sbatch")
array=${array%%;*}
collect=$(sbatch --parsable --dependency="afterany:$array" \
  --output="$OUT/slurm-logs/collect-%j.out" "$HERE/wgslam-collect.sbatch")
collect=${collect%%;*}
echo "array job $array ($N jobs${array_opt:+, one per task})"
echo "collect job $collect (after the array; writes $OUT/report.html)"
