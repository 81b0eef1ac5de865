#!/usr/bin/env bash
# Screenshot of a batch's report (DIR/report.html, from `wgslam batch collect DIR`) with
# headless Chromium, offline: every host name resolves to nothing, so the PNG shows only
# what the report carries itself. Also fails if the HTML loads anything from the network
# (an http(s):// URL in a src=, href= of a <link>, or CSS url()).
#
# Usage: deploy/report-screenshot.sh DIR OUT.png [WIDTHxHEIGHT]   [1600x2400]
# Installs Debian's chromium package when no chromium is on PATH (root only).
set -euo pipefail

if (($# < 2)); then
  echo "usage: $0 DIR OUT.png [WIDTHxHEIGHT]" >&2
  exit 2
fi
report=$(realpath "$1")/report.html
out=$(realpath -m "$2")
size=${3:-1600x2400}
[[ -s $report ]] || {
  echo "report-screenshot: no $report (run: wgslam batch collect $1)" >&2
  exit 1
}

# 1. No network: the report must be self-contained (inline CSS, data: images, no CDN).
remote=$(grep -noiE '(<(script|img|iframe|source|video|audio|embed)[^>]*[[:space:]]src|<link[^>]*[[:space:]]href)[[:space:]]*=[[:space:]]*["'"'"']?[[:space:]]*(https?:)?//[^"'"'"' >]*|url\([[:space:]]*["'"'"']?(https?:)?//[^)]*\)|@import[^;]*//' "$report" || true)
if [[ -n $remote ]]; then
  echo "report-screenshot: $report loads from the network:" >&2
  echo "$remote" >&2
  exit 1
fi

# 2. Chromium from Debian's packages.
browser=$(command -v chromium || command -v chromium-browser || true)
if [[ -z $browser ]]; then
  [[ $(id -u) -eq 0 ]] || {
    echo "report-screenshot: no chromium; apt-get install chromium (as root)" >&2
    exit 1
  }
  echo "report-screenshot: installing chromium from Debian's packages" >&2
  DEBIAN_FRONTEND=noninteractive apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
  browser=$(command -v chromium)
fi

# 3. The screenshot, with a throw-away profile and every host name unresolvable.
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
mkdir -p "$(dirname "$out")"
rm -f "$out"
timeout 120 "$browser" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
  --disable-background-networking --disable-component-update --disable-sync \
  --disable-dev-shm-usage --hide-scrollbars \
  --host-resolver-rules="MAP * ~NOTFOUND" \
  --user-data-dir="$profile" --window-size="${size/x/,}" \
  --screenshot="$out" "file://$report" >"$profile/chromium.log" 2>&1 || {
  tail -n 20 "$profile/chromium.log" >&2
  echo "report-screenshot: chromium failed" >&2
  exit 1
}
[[ -s $out ]] || {
  echo "report-screenshot: chromium wrote no $out" >&2
  exit 1
}
echo "report-screenshot: $out ($size) from $report"
