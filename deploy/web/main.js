// The page's driver: loads the WebAssembly build (pkg/, written by build.sh), hands it the
// bundled frames (data/, copies of assets/icl_living_room_kt2 listed in data/files.json),
// runs dense SLAM through `WebAssembly.promising` (the run suspends on every GPU wait, see
// src/gpu/wait.rs), shows progress, then the command line's summary lines, the trajectory
// against ground truth and the map render. Everything is fetched from this page's own
// origin.
//
// Query parameters: `frames=A..B` (inclusive; default as `wgslam run`: from the first
// frame with ground truth to the last).
// For scripts (deploy/web/test): `document.body.dataset.state` becomes `done` or `error`,
// and `window.wgslam` holds `{ state, error, result, wallSeconds }`.

import init, {
  add_file,
  set_progress,
  result_json,
  render_rgba,
  last_error,
} from "./pkg/wgslam.js";

const ROOT = "assets/icl_living_room_kt2";
const $ = (id) => document.getElementById(id);
window.wgslam = { state: "loading" };

function finish(state, fields) {
  Object.assign(window.wgslam, { state }, fields);
  document.body.dataset.state = state;
}

function fail(message) {
  $("status").textContent = `error: ${message}`;
  $("status").style.color = "#b00";
  finish("error", { error: message });
}

async function main() {
  if (!navigator.gpu) {
    return fail("this browser has no WebGPU (navigator.gpu is missing)");
  }
  if (typeof WebAssembly.promising !== "function" || typeof WebAssembly.Suspending !== "function") {
    return fail("this browser has no JavaScript Promise Integration (WebAssembly.promising)");
  }
  const adapter = await navigator.gpu.requestAdapter();
  const info = adapter?.info;
  const adapterName = info ? [info.vendor, info.architecture, info.description].filter(Boolean).join(" ") : "";
  const wasm = await init({ module_or_path: new URL("./pkg/wgslam_bg.wasm", import.meta.url) });

  $("status").textContent = "loading frames…";
  const list = await (await fetch("data/files.json")).json();
  await Promise.all(
    list.files.map(async (rel) => {
      const response = await fetch(`data/${rel}`);
      if (!response.ok) throw new Error(`data/${rel}: HTTP ${response.status}`);
      add_file(`${ROOT}/${rel}`, new Uint8Array(await response.arrayBuffer()));
    }),
  );

  // Without `frames`, the command line's default: from the first frame with ground truth
  // (-1 asks the module for it) to the last.
  const frames = new URLSearchParams(location.search).get("frames");
  const match = frames === null ? ["", "-1", String(list.frames - 1)] : /^(\d+)\.\.(\d+)$/.exec(frames);
  if (!match) return fail(`frames=${frames}: want A..B`);
  const [first, last] = [Number(match[1]), Number(match[2])];

  const progress = $("progress");
  set_progress((done, total, surfels, ms, status) => {
    progress.max = total;
    progress.value = done;
    $("status").textContent =
      `frame ${done} of ${total}: ${ms.toFixed(0)} ms, ${surfels} surfels, ${status}`;
  });
  $("status").textContent = "starting the GPU…";

  const run = WebAssembly.promising(wasm.wgslam_web_run);
  const t0 = performance.now();
  const rc = await run(first, last);
  const wallSeconds = (performance.now() - t0) / 1e3;
  if (rc !== 0) return fail(last_error() ?? `run returned ${rc}`);

  const result = JSON.parse(result_json());
  $("summary").textContent = [
    `WebGPU adapter: ${adapterName || "(unnamed)"}; ${result.key_kernels} key kernels`,
    ...result.summary,
    `wall time ${wallSeconds.toFixed(1)} s in this tab; ${globalThis.wgslamSuspensions} GPU waits ` +
      `(JSPI suspensions), ${(globalThis.wgslamSuspensions / result.metrics.frames).toFixed(0)} per frame`,
  ].join("\n");
  const aligned = result.estimate_aligned.length > 0;
  drawTrajectory($("trajectory"), aligned ? result.estimate_aligned : result.estimate, result.ground_truth);
  $("trajectory-caption").textContent = aligned
    ? "Camera path from above: ground truth (blue) and the estimate (orange) after the rigid alignment of the aligned ATE."
    : "Camera path from above: the estimate (orange); the sequence has no ground truth.";
  drawMap($("map"), result.render_width, result.render_height, render_rgba());
  $("status").textContent = "done";
  finish("done", { result, wallSeconds, adapterName, suspensions: globalThis.wgslamSuspensions });
}

// Top view: the two world axes along which the ground truth extends most (x and z for
// ICL-NUIM, whose vertical axis is y), equal scale, a scale bar.
function drawTrajectory(canvas, est, gt) {
  const g = canvas.getContext("2d");
  g.fillStyle = "#fff";
  g.fillRect(0, 0, canvas.width, canvas.height);
  const ref = gt.length ? gt : est;
  const extent = [1, 2, 3].map((k) => {
    const v = ref.map((p) => p[k]);
    return Math.max(...v) - Math.min(...v);
  });
  const axes = [1, 2, 3].sort((a, b) => extent[b - 1] - extent[a - 1]).slice(0, 2).sort();
  const all = [...est, ...gt];
  const lo = axes.map((k) => Math.min(...all.map((p) => p[k])));
  const hi = axes.map((k) => Math.max(...all.map((p) => p[k])));
  const margin = 40;
  const scale = Math.min(
    (canvas.width - 2 * margin) / Math.max(hi[0] - lo[0], 1e-6),
    (canvas.height - 2 * margin) / Math.max(hi[1] - lo[1], 1e-6),
  );
  // Centred in the canvas.
  const pad = [
    (canvas.width - (hi[0] - lo[0]) * scale) / 2,
    (canvas.height - (hi[1] - lo[1]) * scale) / 2,
  ];
  const at = (p) => [
    pad[0] + (p[axes[0]] - lo[0]) * scale,
    canvas.height - pad[1] - (p[axes[1]] - lo[1]) * scale,
  ];
  // The ground truth wide and pale under the estimate: at sub-millimetre errors the two
  // lines coincide.
  const path = (points, color, width) => {
    g.strokeStyle = color;
    g.lineWidth = width;
    g.beginPath();
    points.forEach((p, i) => (i ? g.lineTo(...at(p)) : g.moveTo(...at(p))));
    g.stroke();
    g.fillStyle = color;
    for (const p of points) {
      const [x, y] = at(p);
      g.fillRect(x - width, y - width, 2 * width, 2 * width);
    }
  };
  path(gt, "#8fb0e8", 7);
  path(est, "#dc3c1e", 1.5);
  const names = ["x", "y", "z"];
  g.fillStyle = "#222";
  g.font = "14px sans-serif";
  g.fillText(`${names[axes[0] - 1]} →, ${names[axes[1] - 1]} ↑ (world, metres)`, 10, 20);
  g.fillStyle = "#5a86d6";
  g.fillText("ground truth", canvas.width - 210, 20);
  g.fillStyle = "#dc3c1e";
  g.fillText("estimate", canvas.width - 100, 20);
  const bar = [1, 0.5, 0.1, 0.05, 0.01, 0.005, 0.001].find((m) => m * scale <= canvas.width / 3) ?? 0.001;
  const label = bar >= 1 ? `${bar} m` : bar >= 0.01 ? `${bar * 100} cm` : `${bar * 1000} mm`;
  g.strokeStyle = "#222";
  g.beginPath();
  g.moveTo(10, canvas.height - 12);
  g.lineTo(10 + bar * scale, canvas.height - 12);
  g.stroke();
  g.fillStyle = "#222";
  g.fillText(label, 14 + bar * scale, canvas.height - 8);
}

function drawMap(canvas, width, height, rgba) {
  canvas.width = width;
  canvas.height = height;
  const image = new ImageData(new Uint8ClampedArray(rgba.buffer, rgba.byteOffset, rgba.length), width, height);
  canvas.getContext("2d").putImageData(image, 0, 0);
}

// A Rust panic traps the module; src/web.rs leaves its message in `wgslamPanic`.
main().catch((e) => fail(globalThis.wgslamPanic ? `panic: ${globalThis.wgslamPanic}` : (e?.stack ?? String(e))));
