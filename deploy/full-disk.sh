#!/usr/bin/env bash
# Issue 27, item 3: outputs on a full disk are complete or absent as a set.
# Mounts small tmpfs file systems (needs root; exits 77, "skipped", otherwise) and checks
# that `wgslam run` over an earlier run's outputs that runs out of space keeps the old set
# whole and leaves no temporary file or folder, and that `wgslam register` on a full disk
# leaves neither result.json nor aligned.ply.
# Usage: deploy/full-disk.sh [WGSLAM_BINARY]   (default: target/release/wgslam, else debug)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BIN=${1:-}
if [[ -z $BIN ]]; then
  for b in "${CARGO_TARGET_DIR:-target}"/{release,debug}/wgslam; do
    [[ -x $b ]] && BIN=$b && break
  done
fi
[[ -x ${BIN:-} ]] || { echo "no wgslam binary; build it or pass its path" >&2; exit 2; }
if [[ $(id -u) != 0 ]]; then
  echo "SKIPPED: mounting a tmpfs needs root" >&2
  exit 77
fi
MNT=$(mktemp -d /tmp/wgslam-full-disk.XXXXXX)
LOG=$(mktemp /tmp/wgslam-full-disk-log.XXXXXX)
cleanup() { umount "$MNT" 2>/dev/null || true; rmdir "$MNT"; rm -f "$LOG"; }
trap cleanup EXIT
fail() { echo "FAILED: $*" >&2; exit 1; }
run() { "$BIN" run --backend cpu --out "$MNT/out" "$@"; }

# 1. run: the first, small run fits (about 2.2 MB); the second, larger one does not.
mount -t tmpfs -o size=3m tmpfs "$MNT"
run --frames 1..2 --downsample 4 >/dev/null 2>&1 || fail "the small run did not fit"
before=$(sha256sum "$MNT"/out/* | sha256sum)
if run --frames 1..12 --downsample 1 >"$LOG" 2>&1; then
  fail "the large run fitted into 3 MB"
fi
grep -q "No space left" "$LOG" || fail "not a full-disk error: $(tail -2 "$LOG")"
[[ $(sha256sum "$MNT"/out/* | sha256sum) == "$before" ]] || fail "run: the old set changed"
leftovers=$(find "$MNT" -name '.*tmp-*')
[[ -z $leftovers ]] || fail "run: temporaries left: $leftovers"
echo "ok: run on a full disk kept the old set ($(find "$MNT/out" -type f | wc -l) files), no temporaries"
umount "$MNT"

# 2. register: a disk too small for aligned.ply.
mount -t tmpfs -o size=8k tmpfs "$MNT"
PAIR=assets/lidar/fast_gicp_pair/data
if "$BIN" register "$PAIR/251370668.pcd" "$PAIR/251371071.pcd" --out "$MNT/out" >"$LOG" 2>&1; then
  fail "register fitted into 8 kB"
fi
grep -q "No space left" "$LOG" || fail "register: not a full-disk error: $(tail -2 "$LOG")"
[[ ! -e $MNT/out ]] || fail "register left $(ls -A "$MNT/out")"
leftovers=$(find "$MNT" -mindepth 1)
[[ -z $leftovers ]] || fail "register: left $leftovers"
echo "ok: register on a full disk left nothing"
