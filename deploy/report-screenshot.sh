#!/usr/bin/env bash
# Screenshot of a batch's report (DIR/report.html, from `wgslam batch collect DIR`) with
# headless Chromium, offline: every host name resolves to nothing, so the PNG shows only
# what the report carries itself. Also fails if the HTML loads anything from the network
# (an http(s):// or //host URL in a src=, a <link href=>, CSS url() or @import).
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
# An HTML parser, not a regex: the report inlines megabytes of base64 images on one line.
python3 - "$report" <<'PY' || exit 1
import html.parser, re, sys

# Attributes that make a browser fetch something, by tag (<a href> is only a link).
LOADS = {"script": ["src"], "img": ["src", "srcset"], "iframe": ["src"], "frame": ["src"],
         "source": ["src", "srcset"], "video": ["src", "poster"], "audio": ["src"],
         "embed": ["src"], "object": ["data"], "input": ["src"], "track": ["src"],
         "link": ["href"], "image": ["href", "xlink:href"], "use": ["href", "xlink:href"]}
REMOTE = re.compile(r"^\s*(https?:|ftp:)?//", re.I)
CSS_REMOTE = re.compile(r"(url\(\s*[\"']?\s*|@import\s+[\"']?)((https?:)?//[^\"')\s;]*)", re.I)

class Check(html.parser.HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.found, self.in_style = [], False
    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            value = value or ""
            if name in LOADS.get(tag, []) and any(REMOTE.match(v.split()[0]) for v in value.split(",") if v.strip()):
                self.found.append(f"line {self.getpos()[0]}: <{tag} {name}={value[:100]!r}>")
            if name == "style":
                self.css(value)
        self.in_style = tag == "style"
    def handle_endtag(self, tag):
        self.in_style = False
    def handle_data(self, data):
        if self.in_style:
            self.css(data)
    def css(self, text):
        for m in CSS_REMOTE.finditer(text):
            self.found.append(f"line {self.getpos()[0]}: CSS {m.group(2)[:100]}")

c = Check()
with open(sys.argv[1], encoding="utf-8", errors="replace") as f:
    c.feed(f.read())
if c.found:
    print(f"report-screenshot: {sys.argv[1]} loads from the network:", *c.found, sep="\n", file=sys.stderr)
    sys.exit(1)
PY

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
