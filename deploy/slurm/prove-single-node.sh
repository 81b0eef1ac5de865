#!/usr/bin/env bash
# Proof that the Slurm array scripts work: brings up a throw-away single-node Slurm
# cluster on THIS machine (Debian's slurm-wlm and munge packages, daemons started by hand,
# no systemd, no cgroups, no slurmdbd), submits deploy/manifests/proof.toml as a job array
# with deploy/slurm/submit.sh, waits for it and for the dependent collect job, resubmits
# it (every job must then be skipped as complete), runs the same manifest as one plain
# local `wgslam batch`, and checks that `wgslam batch diff` finds the two outputs equal. The daemons are stopped on exit, whatever happens.
#
# Usage (as root, from anywhere):
#   deploy/slurm/prove-single-node.sh               # the whole proof
#   deploy/slurm/prove-single-node.sh --smoke-only  # bring-up + `sbatch --array=0-3 --wrap`
#   deploy/slurm/prove-single-node.sh --up    # the same, and leave the cluster running
#                                             # (prints the SLURM_CONF to export)
#   deploy/slurm/prove-single-node.sh --down  # stop a cluster left running by --up
#
# Environment (all optional):
#   WGSLAM_PROOF_DIR   scratch folder, wiped at the start  [/tmp/wgslam-slurm-proof]
#   WGSLAM_BIN         wgslam binary to use  [REPO/target/release/wgslam, built if stale]
#   MANIFEST           manifest to run  [REPO/deploy/manifests/proof.toml]
#   WGSLAM_PROOF_TIMEOUT_S  longest wait for the array and the collect job, s  [1200]
#   WGSLAM_SLURM_PORT  slurmctld's port; slurmd takes the next one  [16817]
#
# Exit status: 0 when every step passed; non-zero with a "FAILED: ..." line otherwise.
# Re-runnable: daemons left over from an earlier run (killed with SIGKILL, say) are found
# through the pid files in WGSLAM_PROOF_DIR and stopped before the folder is wiped.
set -euo pipefail

SMOKE_ONLY=0 KEEP_UP=0
case "${1:-}" in
  --smoke-only) SMOKE_ONLY=1 ;;
  --up) SMOKE_ONLY=1 KEEP_UP=1 ;;
  --down) DOWN_ONLY=1 ;;
  "") ;;
  *)
    echo "usage: $0 [--smoke-only | --up | --down]" >&2
    exit 2
    ;;
esac

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
WORK=${WGSLAM_PROOF_DIR:-/tmp/wgslam-slurm-proof}
MANIFEST=${MANIFEST:-$REPO/deploy/manifests/proof.toml}
TIMEOUT_S=${WGSLAM_PROOF_TIMEOUT_S:-1200}
CTLD_PORT=${WGSLAM_SLURM_PORT:-16817}
SLURMD_PORT=$((CTLD_PORT + 1))
NODE=$(hostname -s)
T0=$(date +%s.%N)

log() { printf '[prove %6.1fs] %s\n' "$(echo "$(date +%s.%N) - $T0" | bc)" "$*"; }
fail() {
  echo "FAILED: $*" >&2
  exit 1
}
elapsed() { echo "$(date +%s.%N) - $1" | bc | xargs printf '%.1f'; }

[[ $(id -u) -eq 0 ]] || fail "run as root (it installs packages and starts slurmd as root)"

# --- 1. packages -------------------------------------------------------------------------
t=$(date +%s.%N)
need=()
for pair in slurmctld:slurm-wlm slurmd:slurm-wlm sbatch:slurm-wlm munged:munge; do
  command -v "${pair%%:*}" >/dev/null || need+=("${pair#*:}")
done
mapfile -t need < <(printf '%s\n' "${need[@]}" | sort -u | grep .)
if ((${#need[@]})) && [[ -z ${DOWN_ONLY:-} ]]; then
  log "installing ${need[*]} from Debian's packages"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq || fail "apt-get update"
  apt-get install -y -qq slurm-wlm munge >/dev/null || fail "apt-get install slurm-wlm munge"
fi
APT_S=$(elapsed "$t")
log "packages ready ($APT_S s; $(slurmctld -V), $(munged --version | cut -d' ' -f1))"

# --- 2. stop what an earlier run left, start afresh --------------------------------------
stop_pidfile() { # stop_pidfile FILE NAME: TERM, wait up to 10 s, then KILL
  local f=$1 name=$2 pid i
  [[ -f $f ]] || return 0
  pid=$(cat "$f" 2>/dev/null || true)
  rm -f "$f"
  [[ -n $pid ]] && kill -0 "$pid" 2>/dev/null || return 0
  # Only stop the pid if it still is the daemon we started (pids get reused).
  [[ $(cat "/proc/$pid/comm" 2>/dev/null) == "$name" ]] || return 0
  kill -TERM "$pid" 2>/dev/null || true
  for i in $(seq 1 50); do
    kill -0 "$pid" 2>/dev/null || return 0
    sleep 0.2
  done
  kill -KILL "$pid" 2>/dev/null || true
}
stop_daemons() {
  if [[ -f $WORK/slurm.conf ]] && [[ -f $WORK/run/slurmctld.pid ]]; then
    # Cancel what is still queued or running so no slurmstepd outlives its slurmd.
    SLURM_CONF=$WORK/slurm.conf timeout 10 scancel --full --user=root >/dev/null 2>&1 || true
  fi
  stop_pidfile "$WORK/run/slurmd.pid" slurmd
  stop_pidfile "$WORK/run/slurmctld.pid" slurmctld
  stop_pidfile "$WORK/run/munged.pid" munged
}
on_exit() {
  local rc=$?
  if ((KEEP_UP && rc == 0)); then
    log "cluster left running: export SLURM_CONF=$SLURM_CONF; stop it with $0 --down"
    return
  fi
  stop_daemons
  if ((rc != 0)); then
    echo "--- logs under $WORK/log (last lines) ---" >&2
    tail -n 15 "$WORK"/log/*.log 2>/dev/null >&2 || true
  fi
  log "daemons stopped; exit $rc (total $(elapsed "$T0") s)"
}
stop_daemons
if [[ -n ${DOWN_ONLY:-} ]]; then
  log "stopped what ran from $WORK"
  exit 0
fi
rm -rf "$WORK"
mkdir -p "$WORK"
chmod 700 "$WORK"
mkdir -m 700 "$WORK"/{run,log,state,spool}
mkdir -m 711 "$WORK/munge" # munged wants its socket folder searchable by all
trap on_exit EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# --- 3. munge, with its own key and socket (a system munged, if any, is left alone) ------
dd if=/dev/urandom of="$WORK/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$WORK/munge/munge.key"
MUNGE_SOCKET=$WORK/munge/munge.socket
munged --force --key-file="$WORK/munge/munge.key" --socket="$MUNGE_SOCKET" \
  --pid-file="$WORK/run/munged.pid" --log-file="$WORK/log/munged.log" \
  --seed-file="$WORK/munge/munged.seed" || fail "munged did not start (see $WORK/log/munged.log)"
munge -n --socket="$MUNGE_SOCKET" | unmunge --socket="$MUNGE_SOCKET" >/dev/null \
  || fail "munge round trip through $MUNGE_SOCKET"
log "munged up (socket $MUNGE_SOCKET)"

# --- 4. slurm.conf for one node, no cgroups, no accounting daemon -----------------------
CPUS=$(nproc)
MEM_MIB=$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)
export SLURM_CONF=$WORK/slurm.conf
cat >"$SLURM_CONF" <<EOF
# Generated by deploy/slurm/prove-single-node.sh: a throw-away one-node cluster.
ClusterName=wgslam-proof
SlurmctldHost=$NODE(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$MUNGE_SOCKET
CredType=cred/munge
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/run/slurmctld.pid
SlurmdPidFile=$WORK/run/slurmd.pid
SlurmctldLogFile=$WORK/log/slurmctld.log
SlurmdLogFile=$WORK/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# No cgroups here (no systemd, and a container-like VM): track processes by parent pid.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
# No slurmdbd, so no sacct: every finished job is also written to this text file.
JobCompType=jobcomp/filetxt
JobCompLoc=$WORK/log/jobcomp.txt
SwitchType=switch/none
MailProg=/bin/true
MpiDefault=none
SchedulerType=sched/backfill
# Start the next array task as soon as one ends: with the defaults slurmctld waited ~3 s
# between allocations here (a 10-task array of 0.1 s tasks took 18.2 s; with these, 6.1 s).
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
# Keep finished jobs in slurmctld's memory long enough for scontrol to report them.
MinJobAge=3600
ReturnToService=2
SlurmdTimeout=60
InactiveLimit=0
KillWait=10
NodeName=$NODE NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$MEM_MIB State=UNKNOWN
PartitionName=proof Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF
for port in "$CTLD_PORT" "$SLURMD_PORT"; do
  if ss -ltn "sport = :$port" | grep -q LISTEN; then
    fail "port $port is taken; set WGSLAM_SLURM_PORT to a free pair"
  fi
done
slurmctld -i || fail "slurmctld did not start (see $WORK/log/slurmctld.log)"
slurmd || fail "slurmd did not start (see $WORK/log/slurmd.log)"

wait_idle() {
  local i state
  for i in $(seq 1 120); do
    state=$(sinfo -h -n "$NODE" -o %T 2>/dev/null || true)
    [[ $state == idle ]] && return 0
    sleep 0.5
  done
  sinfo -R >&2 || true
  fail "node $NODE is '$state', not idle, after 60 s"
}
wait_idle
log "slurmctld and slurmd up: node $NODE idle ($CPUS CPUs, $MEM_MIB MiB), SLURM_CONF=$SLURM_CONF"

# wait_jobs TIMEOUT_S JOBID...: poll squeue until none of the jobs is pending or running.
wait_jobs() {
  local limit=$1 ids start left
  shift
  ids=$(
    IFS=,
    echo "$*"
  )
  start=$(date +%s)
  while :; do
    left=$(squeue -h -j "$ids" -o %i 2>/dev/null | wc -l)
    ((left == 0)) && return 0
    if (($(date +%s) - start > limit)); then
      squeue -j "$ids" >&2 || true
      fail "jobs $ids still queued or running after $limit s"
    fi
    sleep 2
  done
}

# job_states JOBID: one "JobId=... ArrayTaskId=... JobState=... ExitCode=..." line per task.
job_states() {
  scontrol -o show job "$1" | tr ' ' '\n' \
    | awk -F= '$1 == "JobId" || $1 == "ArrayTaskId" || $1 == "JobState" || $1 == "ExitCode" \
        { printf "%s ", $0 } $1 == "ExitCode" { print "" }'
}

# all_completed JOBID: every task COMPLETED with exit code 0:0, else list the others.
all_completed() {
  local bad
  bad=$(job_states "$1" | grep -v 'JobState=COMPLETED ExitCode=0:0' || true)
  [[ -z $bad ]] || {
    echo "$bad" >&2
    return 1
  }
}

# --- 5. smoke test: a trivial array ------------------------------------------------------
t=$(date +%s.%N)
mkdir -p "$WORK/smoke"
# shellcheck disable=SC2016 # expanded by the task, not here
smoke=$(sbatch --parsable --array=0-3 --output="$WORK/smoke/%A_%a.out" \
  --wrap 'echo "task $SLURM_ARRAY_TASK_ID of $SLURM_ARRAY_TASK_COUNT on $(hostname -s)"')
smoke=${smoke%%;*}
wait_jobs 120 "$smoke"
all_completed "$smoke" || fail "smoke array $smoke: some task did not complete"
for i in 0 1 2 3; do
  grep -qx "task $i of 4 on $NODE" "$WORK/smoke/${smoke}_$i.out" \
    || fail "smoke task $i wrote '$(cat "$WORK/smoke/${smoke}_$i.out" 2>/dev/null)'"
done
log "smoke array $smoke: 4 tasks completed and printed their index ($(elapsed "$t") s)"
if ((SMOKE_ONLY)); then
  log "PASSED (smoke only)"
  exit 0
fi

# --- 6. the binary -----------------------------------------------------------------------
t=$(date +%s.%N)
if [[ -z ${WGSLAM_BIN:-} ]]; then
  WGSLAM_BIN=$REPO/target/release/wgslam
  log "cargo build --release (incremental)"
  (cd "$REPO" && cargo build --release --quiet --bin wgslam) || fail "cargo build --release"
fi
export WGSLAM_BIN
BUILD_S=$(elapsed "$t")
"$WGSLAM_BIN" batch list "$MANIFEST" >"$WORK/list.txt" \
  || fail "$WGSLAM_BIN batch list $MANIFEST (does this binary have the batch command?)"
N_JOBS=$(awk '/^[0-9]+ jobs?( |$)/ { print $1 }' "$WORK/list.txt")
[[ -n $N_JOBS ]] || fail "no 'N jobs' line in 'wgslam batch list' (see $WORK/list.txt)"
log "binary ready ($BUILD_S s): $(tail -n 1 "$WORK/list.txt")"

# GPU (lavapipe) jobs need a runtime dir; the sbatch script makes one if it is unset.
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/xdg}
mkdir -p "$XDG_RUNTIME_DIR"

# --- 7. the array and the dependent collect job, through submit.sh ----------------------
t=$(date +%s.%N)
SLURM_OUT=$WORK/out-slurm
"$REPO/deploy/slurm/submit.sh" "$MANIFEST" "$SLURM_OUT" | tee "$WORK/submit.txt" \
  || fail "deploy/slurm/submit.sh"
array=$(awk '/^array job/ { print $3 }' "$WORK/submit.txt")
collect=$(awk '/^collect job/ { print $3 }' "$WORK/submit.txt")
[[ -n $array && -n $collect ]] || fail "could not read the job ids from submit.sh's output"
wait_jobs "$TIMEOUT_S" "$array" "$collect"
SLURM_S=$(elapsed "$t")
job_states "$array" >"$WORK/array-states.txt"
job_states "$collect" >>"$WORK/array-states.txt"
if ! all_completed "$array"; then
  for task in $(job_states "$array" | grep -v 'JobState=COMPLETED ExitCode=0:0' \
    | sed -n 's/.*ArrayTaskId=\([0-9]*\).*/\1/p'); do
    echo "--- $SLURM_OUT/slurm-logs/batch-${array}_$task.out (last lines) ---" >&2
    tail -n 20 "$SLURM_OUT/slurm-logs/batch-${array}_$task.out" >&2 || true
  done
  fail "array $array: some task failed (logs: $SLURM_OUT/slurm-logs)"
fi
all_completed "$collect" || fail "collect job $collect failed (log: $SLURM_OUT/slurm-logs)"
for f in summary.csv summary.json report.html; do
  [[ -s $SLURM_OUT/$f ]] || fail "collect job wrote no $SLURM_OUT/$f"
done
log "array $array ($N_JOBS tasks) and collect job $collect all COMPLETED 0:0 ($SLURM_S s)"

# --- 8. resubmitting the same array skips every job (outputs complete) ------------------
t=$(date +%s.%N)
"$REPO/deploy/slurm/submit.sh" "$MANIFEST" "$SLURM_OUT" | tee "$WORK/resubmit.txt" \
  || fail "deploy/slurm/submit.sh (resubmission)"
array2=$(awk '/^array job/ { print $3 }' "$WORK/resubmit.txt")
collect2=$(awk '/^collect job/ { print $3 }' "$WORK/resubmit.txt")
wait_jobs "$TIMEOUT_S" "$array2" "$collect2"
all_completed "$array2" || fail "resubmitted array $array2: some task failed"
all_completed "$collect2" || fail "resubmitted collect job $collect2 failed"
skipped=$(cat "$SLURM_OUT/slurm-logs/batch-${array2}"_*.out | grep -c 'outputs complete, skipped' || true)
((skipped == N_JOBS)) \
  || fail "resubmitted array $array2: $skipped of $N_JOBS jobs skipped as complete"
RESUBMIT_S=$(elapsed "$t")
log "resubmitted array $array2: all $skipped jobs skipped as complete ($RESUBMIT_S s)"

# --- 9. the same manifest as one plain local batch, and the diff -------------------------
t=$(date +%s.%N)
LOCAL_OUT=$WORK/out-local
# Outside Slurm: make sure no index or shard variable leaks in, so every job runs.
env -u SLURM_ARRAY_TASK_ID -u SLURM_ARRAY_TASK_COUNT -u JOB_COMPLETION_INDEX \
  -u WGSLAM_SHARD_COUNT "$WGSLAM_BIN" batch "$MANIFEST" --out "$LOCAL_OUT" \
  >"$WORK/log/local-batch.log" 2>&1 || fail "local batch (log: $WORK/log/local-batch.log)"
LOCAL_S=$(elapsed "$t")
log "local batch done ($LOCAL_S s)"
"$WGSLAM_BIN" batch diff "$SLURM_OUT" "$LOCAL_OUT" | tee "$WORK/diff.txt" \
  || fail "batch diff: the Slurm and the local outputs differ (see $WORK/diff.txt)"
log "batch diff: equal"

cat >"$WORK/timings.txt" <<EOF
apt_install_s=$APT_S
build_s=$BUILD_S
slurm_array_and_collect_s=$SLURM_S
slurm_resubmit_s=$RESUBMIT_S
local_batch_s=$LOCAL_S
total_s=$(elapsed "$T0")
EOF
log "PASSED: apt $APT_S s, build $BUILD_S s, Slurm array + collect $SLURM_S s, resubmission $RESUBMIT_S s, local batch $LOCAL_S s"
