#!/usr/bin/env bash
# Builds the browser page into deploy/web/dist (a static folder: serve it from any web
# server, e.g. `python3 -m http.server -d deploy/web/dist`, and open index.html in a
# browser with WebGPU):
#   - the library for wasm32-unknown-unknown (release), as a cdylib, without the
#     reference-types feature (asyncify below cannot rewrite functions holding references;
#     wasm-bindgen then keeps JavaScript objects in its own table instead of externrefs);
#   - its JavaScript bindings by wasm-bindgen-cli, the version Cargo.lock pins for the
#     wasm-bindgen crate (installed here with `cargo install` when missing or different);
#   - two copies of the module: pkg/wgslam_bg.wasm for browsers with JSPI, and
#     pkg/wgslam_bg.asyncify.wasm, rewritten by Binaryen's `wasm-opt --asyncify` so that it
#     can suspend without JSPI (crates/gpu/src/wait.rs, deploy/web/suspend.js). Needs
#     wasm-opt (Debian: apt-get install binaryen);
#   - the page (index.html and its scripts) and copies of the bundled frames
#     (assets/icl_living_room_kt2) with data/files.json listing them and their sizes.
# Each step says what it does before it starts (the first build takes minutes).
set -euo pipefail
cd "$(dirname "$0")/../.."
step() { echo "build.sh: $*"; }

if ! command -v wasm-opt >/dev/null; then
  echo "build.sh: wasm-opt is missing: install Binaryen (Debian and Ubuntu: apt-get install binaryen)" >&2
  exit 1
fi
if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
  step "adding the wasm32-unknown-unknown target to the Rust toolchain (once)"
  rustup target add wasm32-unknown-unknown >/dev/null 2>&1 || true
fi
# The bindings tool must match the crate exactly, or it refuses the module.
want=$(awk '$0 == "name = \"wasm-bindgen\"" { getline; gsub(/"/, "", $3); print $3; exit }' Cargo.lock)
have=$(wasm-bindgen --version 2>/dev/null | awk '{ print $2 }' || true)
if [[ "$have" != "$want" ]]; then
  step "installing wasm-bindgen-cli $want once into ~/.cargo/bin (found: ${have:-none});" \
    "it compiles from source, about 3-4 minutes on 2 cores, and is reused afterwards"
  # Not --locked: the tool's own lock file pins a webpki-roots release that crates.io
  # mirrors do not all carry; the version of the tool itself is pinned all the same.
  cargo install wasm-bindgen-cli --version "$want"
else
  step "wasm-bindgen-cli $want is installed ($(command -v wasm-bindgen)); reusing it"
fi

step "compiling the library for wasm32 (release; the first time compiles every dependency," \
  "a few minutes)"
# No debug info: wasm-bindgen would drop it anyway, and it triples the link's input.
CARGO_PROFILE_RELEASE_DEBUG=false \
  CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS="-C target-feature=-reference-types" \
  cargo rustc --lib --release --target wasm32-unknown-unknown --crate-type cdylib
# The standard library comes built with reference types, and its feature list in the
# module's target_features section would make wasm-bindgen use externrefs; without the
# section it does not.
built=target/wasm32-unknown-unknown/release/wgslam.wasm
plain=target/wasm32-unknown-unknown/release/wgslam-page.wasm
wasm-opt --detect-features --strip-target-features "$built" -o "$plain"

dist=deploy/web/dist
rm -rf "$dist"
mkdir -p "$dist/pkg" "$dist/data"
step "writing the JavaScript bindings (wasm-bindgen) and the page into $dist"
wasm-bindgen --target web --no-typescript --out-dir "$dist/pkg" --out-name wgslam "$plain"
step "writing the asyncify copy of the module (wasm-opt --asyncify -O2, about a minute)"
# The features Rust's wasm32 target uses, less reference types (the section that listed
# them is gone). Only functions on a path to the `suspend` import (or to an indirect call)
# are rewritten.
wasm-opt --enable-bulk-memory --enable-multivalue --enable-mutable-globals \
  --enable-nontrapping-float-to-int --enable-sign-ext \
  --asyncify --pass-arg=asyncify-imports@wgslam_suspend.suspend -O2 \
  "$dist/pkg/wgslam_bg.wasm" -o "$dist/pkg/wgslam_bg.asyncify.wasm"
cp deploy/web/index.html deploy/web/main.js deploy/web/suspend.js deploy/web/plot.js \
  deploy/web/picker.js "$dist/"

data=assets/icl_living_room_kt2
cp -r "$data"/. "$dist/data/"
frames=$(grep -cEv '^[[:space:]]*(#|$)' "$data/associations.txt")
{
  printf '{ "frames": %d, "files": [\n' "$frames"
  (cd "$data" && find . -type f -printf '%P %s\n' | sort |
    awk '{ printf "  { \"path\": \"%s\", \"size\": %d }\n", $1, $2 }' | paste -sd, -)
  printf ']}\n'
} >"$dist/data/files.json"
echo "built $dist ($(du -sh "$dist" | cut -f1)): $frames frames; wasm $(du -h "$dist/pkg/wgslam_bg.wasm" | cut -f1)," \
  "asyncify copy $(du -h "$dist/pkg/wgslam_bg.asyncify.wasm" | cut -f1)"
