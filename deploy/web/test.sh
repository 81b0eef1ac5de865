#!/usr/bin/env bash
# The browser page as a user drives it, against the command line on the same data: builds
# the page (build.sh; skipped with --no-build), runs `wgslam run` natively on the GPU with
# the portable kernels and WebGPU's default limits (what a browser tab gets) over a
# sequence folder that is not in the bundled ICL-NUIM layout, then test/check.mjs loads the
# page in headless Debian Chromium (WebGPU through SwiftShader), picks that folder through
# the page's folder picker, runs the same frames, downloads the outputs and compares them
# with the native ones, turns the map view, and checks the page's error texts (no WebGPU,
# no adapter, not a secure context, opened from disk). It saves screenshots.
#
#   deploy/web/test.sh [--no-build] [FRAMES]       FRAMES: A..B (default 0..9)
#
# The folder: ../shared/data/7scenes_redkitchen (7-Scenes frame files, research licence:
# read from ../shared, never copied into the repository) when present, else the bundled
# ICL-NUIM frames rewritten in the TUM RGB-D layout (rgb.txt, depth.txt, groundtruth.txt,
# camera.json) under $WGSLAM_WEB_OUT (also with WGSLAM_WEB_DATA=bundled, e.g. to check that
# path where ../shared exists). The first line of output says which.
#
# Needs: /usr/bin/chromium (Debian's `chromium`), node and npm, a Vulkan driver (lavapipe)
# for the native run. WGSLAM_BIN: the native binary (default: cargo run --release).
# WGSLAM_WEB_OUT: where the native outputs and the screenshots go (default /tmp/wgslam-web).
set -euo pipefail
cd "$(dirname "$0")/../.."
step() { echo "test.sh: $*"; }

build=1
if [[ "${1:-}" == "--no-build" ]]; then
  build=0
  shift
fi
frames="${1:-0..9}"
out="${WGSLAM_WEB_OUT:-/tmp/wgslam-web}"
mkdir -p "$out"

# The bundled ICL-NUIM frames rewritten in the TUM layout in folder $1, with their
# camera.json unless $2 is "no-camera".
icl_as_tum() {
  local icl=assets/icl_living_room_kt2 to="$1"
  rm -rf "$to"
  mkdir -p "$to"
  cp -r "$icl/rgb" "$icl/depth" "$to/"
  [[ "${2:-}" == no-camera ]] || cp "$icl/camera.json" "$to/"
  # ICL-NUIM's stamps are frame indices: the same numbers serve as TUM stamps.
  awk '!/^[[:space:]]*(#|$)/ { print $3, $4 }' "$icl/associations.txt" >"$to/rgb.txt"
  awk '!/^[[:space:]]*(#|$)/ { print $1, $2 }' "$icl/associations.txt" >"$to/depth.txt"
  cp "$icl"/*.gt.freiburg "$to/groundtruth.txt"
}

folder=../shared/data/7scenes_redkitchen
if [[ -d "$folder" && "${WGSLAM_WEB_DATA:-}" != bundled ]]; then
  folder="$(cd "$folder" && pwd)"
  step "data: $folder (7-Scenes frame files from ../shared), frames $frames"
else
  icl=assets/icl_living_room_kt2
  folder="$out/icl_as_tum"
  why="../shared/data/7scenes_redkitchen is absent"
  [[ "${WGSLAM_WEB_DATA:-}" == bundled ]] && why="WGSLAM_WEB_DATA=bundled"
  step "data ($why): the bundled ICL-NUIM frames rewritten in the TUM layout in" \
    "$folder, frames $frames"
  icl_as_tum "$folder"
fi

# The camera box: a TUM folder without intrinsics (default: the bundled frames in the TUM
# layout without camera.json, and ICL-NUIM's four numbers typed in; WGSLAM_WEB_CAMERA_FOLDER,
# WGSLAM_WEB_CAMERA (a preset such as fr1, or fx,fy,cx,cy) and WGSLAM_WEB_CAMERA_FRAMES
# choose another, e.g. a TUM RGB-D recording with fr1).
camera_folder="${WGSLAM_WEB_CAMERA_FOLDER:-$out/icl_as_tum_no_camera}"
camera="${WGSLAM_WEB_CAMERA:-481.2,-480,319.5,239.5}"
camera_frames="${WGSLAM_WEB_CAMERA_FRAMES:-0..4}"
if [[ -z "${WGSLAM_WEB_CAMERA_FOLDER:-}" ]]; then
  icl_as_tum "$camera_folder" no-camera
fi
camera_flag=(--intrinsics "$camera")
[[ "$camera" == *,* ]] || camera_flag=(--camera "$camera")
step "camera box: $camera_folder with ${camera_flag[*]}, frames $camera_frames"

if ((build)); then
  step "building the page (deploy/web/build.sh)"
  deploy/web/build.sh
fi
step "installing the test's Node packages (playwright-core, pinned; reused when present)"
(cd deploy/web/test && npm ci --no-audit --no-fund --silent)

native=("${WGSLAM_BIN:-}")
if [[ -z "${WGSLAM_BIN:-}" ]]; then
  step "building the native binary (cargo build --release; minutes the first time)"
  cargo build --release --quiet
  native=(target/release/wgslam)
fi
rm -rf "$out/native"
# The page runs every second pixel (docs/full-resolution.md, "The default resolution"), so
# the native runs it is held to say --downsample 2 (a native GPU run's default is 1).
step "the native run: ${native[*]} run --backend gpu --downsample 2 --frames $frames (portable kernels, WebGPU limits)"
WGSLAM_GPU_FEATURES=portable WGSLAM_GPU_LIMITS=webgpu \
  "${native[@]}" run --backend gpu --downsample 2 --frames "$frames" --out "$out/native" "$folder" | tee "$out/native.log"

rm -rf "$out/native-camera"
step "the native run of the camera folder: ${camera_flag[*]} --frames $camera_frames"
WGSLAM_GPU_FEATURES=portable WGSLAM_GPU_LIMITS=webgpu \
  "${native[@]}" run --backend gpu --downsample 2 "${camera_flag[@]}" --frames "$camera_frames" \
  --out "$out/native-camera" "$camera_folder" | tee "$out/native-camera.log"

step "the page in headless Chromium (SwiftShader WebGPU): pick, run, download, turn, errors"
node deploy/web/test/check.mjs --dist deploy/web/dist --folder "$folder" --frames "$frames" \
  --native "$out/native" --shots "$out" --camera-folder "$camera_folder" \
  --camera-setting "$camera" --camera-frames "$camera_frames" --camera-native "$out/native-camera"
