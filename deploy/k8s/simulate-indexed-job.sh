#!/usr/bin/env bash
# Runs deploy/k8s/indexed-job.yaml's pods on this machine, without Kubernetes: reads the
# Job's `completions`, `parallelism`, container command and env from the YAML, maps the
# volume's /data to a local folder, starts one process per completion index with
# JOB_COMPLETION_INDEX set (at most `parallelism` at once), then collect-job.yaml's
# command, and checks with `wgslam batch diff` that the result equals one plain local
# batch of the same manifest. It checks the Job's command, env and sizing against the
# CLI; it does not check Kubernetes itself (scheduling, volumes, retries, images).
#
# Usage: deploy/k8s/simulate-indexed-job.sh [MANIFEST]  [deploy/manifests/k8s-example.toml]
# Environment: WGSLAM_BIN [target/release/wgslam]; DATA_DIR: the sequences the manifest
# names, linked into the simulated volume [/work/shared/data or ../shared/data];
# WGSLAM_SIM_DIR scratch folder, wiped first [/tmp/wgslam-k8s-sim].
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
MANIFEST=$(realpath "${1:-$REPO/deploy/manifests/k8s-example.toml}")
WGSLAM_BIN=${WGSLAM_BIN:-$REPO/target/release/wgslam}
DATA_DIR=${DATA_DIR:-$(realpath "$REPO/../shared/data")}
SIM=${WGSLAM_SIM_DIR:-/tmp/wgslam-k8s-sim}
fail() {
  echo "FAILED: $*" >&2
  exit 1
}
[[ -x $WGSLAM_BIN ]] || fail "no wgslam binary at $WGSLAM_BIN (cargo build --release)"

# The Job's and the collect Job's fields, one shell-quoted assignment per line.
eval "$(python3 - "$HERE/indexed-job.yaml" "$HERE/collect-job.yaml" <<'PY'
import shlex, sys, yaml
def job(path, name):
    for d in yaml.safe_load_all(open(path)):
        if d and d["kind"] == "Job" and d["metadata"]["name"] == name:
            return d
    sys.exit(f"no Job {name} in {path}")
batch = job(sys.argv[1], "wgslam-batch")
collect = job(sys.argv[2], "wgslam-collect")
c = batch["spec"]["template"]["spec"]["containers"][0]
assert batch["spec"]["completionMode"] == "Indexed", "the batch Job is not Indexed"
print(f"COMPLETIONS={batch['spec']['completions']}")
print(f"PARALLELISM={batch['spec'].get('parallelism', 1)}")
print("POD_CMD=(" + " ".join(shlex.quote(a) for a in c["command"]) + ")")
print("POD_ENV=(" + " ".join(shlex.quote(f"{e['name']}={e['value']}") for e in c.get("env", [])) + ")")
cc = collect["spec"]["template"]["spec"]["containers"][0]
print("COLLECT_CMD=(" + " ".join(shlex.quote(a) for a in cc["command"]) + ")")
PY
)"

rm -rf "$SIM"
mkdir -p "$SIM/data" "$SIM/run"
cp "$MANIFEST" "$SIM/data/manifest.toml"
for seq in "$DATA_DIR"/*/; do ln -s "${seq%/}" "$SIM/data/$(basename "$seq")"; done
# /data/... in the pod's command and env -> $SIM/data/...; `wgslam` -> the binary.
map() { sed "s#^/data#$SIM/data#; s#^wgslam\$#$WGSLAM_BIN#" <<<"$1"; }
pod=() env=() collect=()
for a in "${POD_CMD[@]}"; do pod+=("$(map "$a")"); done
for e in "${POD_ENV[@]}"; do env+=("${e%%=*}=$(map "${e#*=}")"); done
for a in "${COLLECT_CMD[@]}"; do collect+=("$(map "$a")"); done

n=$("$WGSLAM_BIN" batch list "$SIM/data/manifest.toml" | awk '/^[0-9]+ jobs?( |$)/ { print $1 }')
((n == COMPLETIONS)) || fail "the manifest has $n jobs, the Job's completions is $COMPLETIONS"
echo "simulating $COMPLETIONS pods, $PARALLELISM at once: ${POD_CMD[*]} (${POD_ENV[*]})"

t=$(date +%s.%N)
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp/xdg}
mkdir -p "$XDG_RUNTIME_DIR"
run_pod() { # run_pod INDEX: one pod, its output in $SIM/run/pod-INDEX.log
  env -u SLURM_ARRAY_TASK_ID -u SLURM_ARRAY_TASK_COUNT "${env[@]}" JOB_COMPLETION_INDEX="$1" \
    "${pod[@]}" >"$SIM/run/pod-$1.log" 2>&1
  echo "$?" >"$SIM/run/pod-$1.rc"
}
running=0
for ((i = 0; i < COMPLETIONS; i++)); do
  run_pod "$i" &
  running=$((running + 1))
  if ((running >= PARALLELISM)); then
    wait -n
    running=$((running - 1))
  fi
done
wait
bad=0
for ((i = 0; i < COMPLETIONS; i++)); do
  rc=$(cat "$SIM/run/pod-$i.rc")
  picked=$(grep -o '[0-9]* of [0-9]* jobs (index [0-9]* of [0-9]*, from [A-Za-z_ ]*' "$SIM/run/pod-$i.log" || true)
  echo "pod $i: exit $rc: $picked"
  ((rc == 0)) || bad=1
done
((bad == 0)) || fail "some pod failed (logs: $SIM/run)"
"${collect[@]}" >"$SIM/run/collect.log" 2>&1 || fail "collect (log: $SIM/run/collect.log)"
echo "pods + collect: $(echo "$(date +%s.%N) - $t" | bc) s; $(tail -n 1 "$SIM/run/collect.log")"

env -u SLURM_ARRAY_TASK_ID -u SLURM_ARRAY_TASK_COUNT -u JOB_COMPLETION_INDEX -u WGSLAM_SHARD_COUNT \
  "$WGSLAM_BIN" batch "$SIM/data/manifest.toml" --out "$SIM/local" >"$SIM/run/local.log" 2>&1 \
  || fail "local batch (log: $SIM/run/local.log)"
"$WGSLAM_BIN" batch diff "$SIM/data/out" "$SIM/local" || fail "the pods' batch differs from the local one"
echo "PASSED"
