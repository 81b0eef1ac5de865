#!/usr/bin/env bash
# The browser build against the command line on the same frames: builds the page
# (build.sh; skipped with --no-build), runs `wgslam run` natively on the GPU with the
# portable kernels and WebGPU's default limits (what a browser tab gets), then
# test/check.mjs loads the page in headless Debian Chromium (WebGPU through SwiftShader),
# waits for its run and compares its ATE with the native one; it saves a screenshot.
#
#   deploy/web/test.sh [--no-build] [FRAMES]       FRAMES: A..B, default every bundled frame
#
# Needs: /usr/bin/chromium (Debian's `chromium`), node and npm, a Vulkan driver (lavapipe)
# for the native run. WGSLAM_BIN: the native binary (default: cargo run --release).
# WGSLAM_WEB_OUT: where the native outputs and the screenshot go (default /tmp/wgslam-web).
set -euo pipefail
cd "$(dirname "$0")/../.."

build=1
if [[ "${1:-}" == "--no-build" ]]; then
  build=0
  shift
fi
frames="${1:-}"
out="${WGSLAM_WEB_OUT:-/tmp/wgslam-web}"
mkdir -p "$out"

if ((build)); then
  deploy/web/build.sh
fi
(cd deploy/web/test && npm ci --no-audit --no-fund --silent)

native=("${WGSLAM_BIN:-}")
if [[ -z "${WGSLAM_BIN:-}" ]]; then
  native=(cargo run --release --quiet --)
fi
frame_args=()
[[ -n "$frames" ]] && frame_args=(--frames "$frames")
rm -rf "$out/native"
WGSLAM_GPU_FEATURES=portable WGSLAM_GPU_LIMITS=webgpu \
  "${native[@]}" run --backend gpu "${frame_args[@]}" --out "$out/native" | tee "$out/native.log"

node deploy/web/test/check.mjs --dist deploy/web/dist --native-metrics "$out/native/metrics.json" \
  --screenshot "$out/page.png" ${frames:+--frames "$frames"}
