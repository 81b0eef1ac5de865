#!/usr/bin/env bash
# deploy/gpu-check.sh: the real-GPU check of issue 33 in one go, for a user (or a lent
# machine) with a GPU: bench at 640x480 and 320x240, compare in lockstep and free mode, and
# the concurrent batch when the binary has one; and issue 48's throughput targets (group
# `throughput`): `wgslam run` on 7-Scenes 0..299 at 640x480 (wall time of the whole
# command), start-up of a one-frame run with an empty and then a filled pipeline cache, 16
# jobs of 150 frames at 16 offsets with `batch --concurrent 16` (each stream submitting on
# its own, and with `--gpu-submissions combined`), and the CPU reference's
# ms/frame at 640x480 (`bench --backends cpu`), each against the baseline binary in the same
# run when one is given; writes ONE JSON with every command, its exit status, its wall time
# and its JSON output (or the tail of its log).
#
#   deploy/gpu-check.sh                      # target/release/wgslam, data in ../shared/data
#   WGSLAM_BASE_BIN=/path/to/old/wgslam deploy/gpu-check.sh   # also bench a baseline
#
# Environment:
#   WGSLAM_BIN        the binary to check (default target/release/wgslam)
#   WGSLAM_BASE_BIN   a baseline binary: benched too, in A-B-B-A order per resolution
#   WGSLAM_DATA       the data folder (default ../shared/data): 7scenes_redkitchen and
#                     icl_living_room_kt2_noisy
#   OUT               write $OUT/gpu-check.json (default ./gpu-check.json)
#   WGSLAM_CHECK_QUICK=1   tiny frame ranges (a smoke test of this script, e.g. on lavapipe)
#   WGSLAM_CHECK_ROUNDS    whole-frame rounds per bench (default 2)
#   WGSLAM_CHECK_STEPS     which groups to run, any of "bench compare batch throughput"
#                          (default all)
#
# Every step runs whatever the steps before it did (a failing command is recorded, not
# fatal); the script exits 1 when any step failed, 0 otherwise. Sized for about 6 minutes
# on an H100: benches over 7-Scenes 0..199 at 7.5 ms/frame or less are seconds each, the
# CPU reference inside compare is most of the time.
set -uo pipefail

BIN=${WGSLAM_BIN:-target/release/wgslam}
BASE=${WGSLAM_BASE_BIN:-}
DATA=${WGSLAM_DATA:-../shared/data}
ROUNDS=${WGSLAM_CHECK_ROUNDS:-2}
JSON=${OUT:-.}/gpu-check.json
SCENES=$DATA/7scenes_redkitchen
NOISY=$DATA/icl_living_room_kt2_noisy
if [ "${WGSLAM_CHECK_QUICK:-0}" = 1 ]; then
  BENCH_FRAMES=0..3 LOCK_FRAMES=0..2 FREE_FRAMES=1..3 BATCH_SPAN=1
  RUN_FRAMES=0..3 JOB_SPAN=1 JOB_STEP=1 CPU_FRAMES=0..1
else
  BENCH_FRAMES=0..199 LOCK_FRAMES=0..40 FREE_FRAMES=1..40 BATCH_SPAN=99
  # Issue 48: 16 jobs of 150 frames, at offsets 0, 9, ..., 135 (7-Scenes 0..284).
  RUN_FRAMES=0..299 JOB_SPAN=149 JOB_STEP=9 CPU_FRAMES=0..40
fi
GROUPS_RUN=" ${WGSLAM_CHECK_STEPS:-bench compare batch throughput} "
wants() { [[ "$GROUPS_RUN" == *" $1 "* ]]; }
# offers OPTION CMD...: whether `CMD --help` mentions OPTION. grep reads the whole text:
# `grep -q` would stop early, and under pipefail the help's SIGPIPE would fail the test.
offers() { local opt=$1; shift; "$@" --help 2>/dev/null | grep -c -- "$opt" >/dev/null; }

WORK=$(mktemp -d "${TMPDIR:-/tmp}/gpu-check.XXXXXX")
STEPS=()
FAILED=0

# JSON string of stdin (backslashes, quotes, tabs, control characters; lines joined by \n).
json_string() {
  printf '"'
  tr -d '\000-\010\013-\037' | sed -e 's/\\/\\\\/g' -e 's/"/\\"/g' -e 's/\t/\\t/g' \
    | awk 'NR > 1 { printf "\\n" } { printf "%s", $0 }'
  printf '"'
}

# step NAME JSON_FILE -- COMMAND...: runs COMMAND, records it with its exit status, wall
# time, the JSON it wrote to JSON_FILE (when that file holds any), and its log's last lines.
step() {
  local name=$1 out=$2
  shift 3
  local log=$WORK/$name.log
  echo "== $name: $*" >&2
  local t0 t1 rc
  t0=$(date +%s.%N)
  "$@" >"$log" 2>&1
  rc=$?
  t1=$(date +%s.%N)
  [ "$rc" = 0 ] || FAILED=1
  echo "   exit $rc after $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }') s" >&2
  local result=null
  if [ -n "$out" ] && [ -s "$out" ]; then
    result=$(cat "$out")
  fi
  local cmd
  cmd=$(printf '%s ' "$@" | json_string)
  STEPS+=("{\"name\": \"$name\", \"command\": $cmd, \"exit_status\": $rc, \"wall_s\": $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }'), \"result\": $result, \"log_tail\": $(tail -n 40 "$log" | json_string)}")
}

# A note in the JSON for a step that was skipped, and why.
skip() {
  echo "== $1: skipped ($2)" >&2
  STEPS+=("{\"name\": \"$1\", \"skipped\": $(printf '%s' "$2" | json_string)}")
}

# gpu_jobs_manifest NAME JOBS STEP SPAN: a batch manifest of JOBS GPU jobs over 7-Scenes
# at 640x480, job j on frames j*STEP .. j*STEP+SPAN.
gpu_jobs_manifest() {
  local name=$1 jobs=$2 stride=$3 span=$4
  echo "output = \"unused\""
  echo "[defaults]"
  echo "downsample = 1"
  echo "profile = \"robust\""
  echo "backend = \"gpu\""
  echo "[[grid]]"
  echo "name = \"$name\""
  echo "sequence = [\"$SCENES\"]"
  printf 'frames = ['
  for ((j = 0; j < jobs; j++)); do
    [ "$j" = 0 ] || printf ', '
    printf '"%d..%d"' $((j * stride)) $((j * stride + span))
  done
  echo ']'
}

# bench LABEL BINARY DOWNSAMPLE: the GPU backend over 7-Scenes BENCH_FRAMES.
bench() {
  local label=$1 bin=$2 ds=$3
  step "bench-$label-ds$ds" "$WORK/bench-$label-ds$ds.json" -- \
    "$bin" bench "$SCENES" --frames "$BENCH_FRAMES" --downsample "$ds" --backends gpu \
    --rounds "$ROUNDS" --json "$WORK/bench-$label-ds$ds.json"
}

if command -v nvidia-smi >/dev/null; then
  step gpu-info "" -- nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
else
  skip gpu-info "no nvidia-smi"
fi
step version "" -- "$BIN" --version

# Benches: candidate and baseline in A-B-B-A order per resolution (a machine whose speed
# drifts favours neither), the candidate's first one with per-kernel GPU times.
if wants bench; then
for ds in 1 2; do
  if [ -n "$BASE" ]; then
    bench new-a "$BIN" "$ds"
    bench base-a "$BASE" "$ds"
    bench base-b "$BASE" "$ds"
    bench new-b "$BIN" "$ds"
  else
    bench new "$BIN" "$ds"
  fi
done
step bench-new-kernels "$WORK/bench-kernels.json" -- \
  "$BIN" bench "$SCENES" --frames "$BENCH_FRAMES" --downsample 1 --backends gpu --kernels \
  --json "$WORK/bench-kernels.json"
fi

# The comparisons of the issue's closing note.
if wants compare; then
step compare-lockstep-7scenes "$WORK/compare-lockstep.json" -- \
  "$BIN" compare "$SCENES" --frames "$LOCK_FRAMES" --downsample 1 \
  --json "$WORK/compare-lockstep.json"
step compare-free-noisy-assignment "$WORK/compare-free.json" -- \
  "$BIN" compare "$NOISY" --frames "$FREE_FRAMES" --free --profile assignment \
  --json "$WORK/compare-free.json"
fi

# Many sequences on one GPU: the same 8 GPU jobs one at a time and 8 at once, where the
# binary can run jobs concurrently; outputs must be identical.
if ! wants batch; then
  skip batch-concurrent "not in WGSLAM_CHECK_STEPS"
elif offers --concurrent "$BIN" batch; then
  manifest=$WORK/concurrent.toml
  gpu_jobs_manifest c 8 12 "$BATCH_SPAN" >"$manifest"
  for n in 1 2 4 8; do
    # Frames/s of all jobs: 8 x (BATCH_SPAN + 1) frames over the step's wall_s.
    step "batch-concurrent-$n" "$WORK/batch-$n/summary.json" -- \
      "$BIN" batch "$manifest" --out "$WORK/batch-$n" --concurrent "$n"
  done
  for n in 2 4 8; do
    step "batch-concurrent-$n-same-outputs" "" -- bash -c '
      status=0
      for f in "$1"/jobs/*/gpu/trajectory.tum "$1"/jobs/*/gpu/map.ply; do
        g=$2/${f#"$1"/}
        cmp "$f" "$g" || status=1
      done
      ls "$1"/jobs/*/gpu/map.ply | wc -l
      exit $status' _ "$WORK/batch-1" "$WORK/batch-$n"
  done
else
  skip batch-concurrent "this wgslam has no 'batch --concurrent'"
fi

# Issue 48's targets. `run` and start-up: the wall time of the whole command is the step's
# wall_s. Start-up: a one-frame run twice over one new pipeline-cache folder (the first
# fills it, the second is the "second run" of the target; a binary without the cache runs
# the same). The 16-job batch: frames/s = 16 x (JOB_SPAN + 1) / wall_s.
throughput() {
  local label=$1 bin=$2
  step "run-wall-$label" "" -- "$bin" run "$SCENES" --frames "$RUN_FRAMES" --downsample 1 \
    --backend gpu --out "$WORK/run-$label"
  local cache=$WORK/pipeline-cache-$label
  mkdir -p "$cache"
  for turn in first second; do
    step "startup-$turn-$label" "" -- env WGSLAM_PIPELINE_CACHE="$cache" \
      "$bin" run "$SCENES" --frames 0..0 --downsample 1 --backend gpu --out "$WORK/one-$label"
  done
  local manifest=$WORK/jobs16.toml
  gpu_jobs_manifest j 16 "$JOB_STEP" "$JOB_SPAN" >"$manifest"
  step "batch16-concurrent16-$label" "$WORK/batch16-$label/summary.json" -- \
    "$bin" batch "$manifest" --out "$WORK/batch16-$label" --concurrent 16
  # Shared waits (issue 48 item 2): 16 GPU streams in one process, waits and submissions
  # per stream-frame against one stream, where the binary has `bench --streams`.
  if offers --streams "$bin" bench; then
    step "streams16-$label" "$WORK/streams16-$label.json" -- \
      "$bin" bench "$SCENES" --frames "$BENCH_FRAMES" --downsample 1 --streams 16 \
      --json "$WORK/streams16-$label.json"
  fi
  # Combined submissions (issue 48 item 2's second half; not the default until a GPU shows
  # they pay): the same batch and streams with `--gpu-submissions combined`, outputs the
  # same bytes as the default's.
  if offers --gpu-submissions "$bin"; then
    step "batch16-concurrent16-combined-$label" "$WORK/batch16-combined-$label/summary.json" -- \
      "$bin" --gpu-submissions combined batch "$manifest" \
      --out "$WORK/batch16-combined-$label" --concurrent 16
    step "batch16-combined-same-outputs-$label" "" -- bash -c '
      status=0
      for f in "$1"/jobs/*/gpu/trajectory.tum "$1"/jobs/*/gpu/map.ply; do
        cmp "$f" "$2/${f#"$1"/}" || status=1
      done
      ls "$1"/jobs/*/gpu/map.ply | wc -l
      exit $status' _ "$WORK/batch16-$label" "$WORK/batch16-combined-$label"
    step "streams16-combined-$label" "$WORK/streams16-combined-$label.json" -- \
      "$bin" --gpu-submissions combined bench "$SCENES" --frames "$BENCH_FRAMES" \
      --downsample 1 --streams 16 --json "$WORK/streams16-combined-$label.json"
  fi
  step "cpu-reference-ds1-$label" "$WORK/cpu-$label.json" -- \
    "$bin" bench "$SCENES" --frames "$CPU_FRAMES" --downsample 1 --backends cpu --rounds 1 \
    --json "$WORK/cpu-$label.json"
  # The reference on one thread against every core, frame by frame in one process (issue
  # 48 item 5), where the binary has `bench --thread-scaling`.
  if offers --thread-scaling "$bin" bench; then
    step "cpu-thread-scaling-ds1-$label" "$WORK/cpu-threads-$label.json" -- \
      "$bin" bench "$SCENES" --frames "$CPU_FRAMES" --downsample 1 --thread-scaling \
      --json "$WORK/cpu-threads-$label.json"
  fi
}
if wants throughput; then
  throughput new "$BIN"
  if [ -n "$BASE" ]; then
    throughput base "$BASE"
    step compare-lockstep-7scenes-base "$WORK/compare-lockstep-base.json" -- \
      "$BASE" compare "$SCENES" --frames "$LOCK_FRAMES" --downsample 1 \
      --json "$WORK/compare-lockstep-base.json"
  fi
fi

{
  printf '{\n"binary": %s,\n' "$(printf '%s' "$BIN" | json_string)"
  printf '"baseline": %s,\n' "$(printf '%s' "$BASE" | json_string)"
  printf '"data": %s,\n' "$(printf '%s' "$DATA" | json_string)"
  printf '"batch_frames": %d,\n' $((8 * (BATCH_SPAN + 1)))
  printf '"batch16_frames": %d,\n' $((16 * (JOB_SPAN + 1)))
  printf '"quick": %s,\n' "$([ "${WGSLAM_CHECK_QUICK:-0}" = 1 ] && echo true || echo false)"
  printf '"failed": %s,\n"steps": [\n' "$([ "$FAILED" = 1 ] && echo true || echo false)"
  for i in "${!STEPS[@]}"; do
    [ "$i" = 0 ] || printf ',\n'
    printf '%s' "${STEPS[$i]}"
  done
  printf '\n]\n}\n'
} >"$JSON"
echo "wrote $JSON (work files in $WORK)" >&2
exit "$FAILED"
