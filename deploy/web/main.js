// The page's driver. First it checks what the browser offers (a secure context, WebGPU, an
// adapter), before fetching the module or any data, and says what to do when
// something is missing. Then the user picks the data (the bundled frames, a folder from the
// picker, or a dropped folder), a frame range and a profile, and runs: the module opens the
// folder with the command line's dataset code (src/web: the file list goes over up front,
// each file's bytes are read from the browser only when a frame needs them), runs dense
// SLAM through suspend.js's `call` (every GPU wait and file read suspends the module: through
// JSPI where the browser has it, else through the asyncify build; crates/gpu/src/wait.rs),
// and calls back after each frame with the input frame's pictures and,
// every few frames, the map drawn from the user's view. Afterwards: the command line's
// summary, the trajectory plot, the outputs to download and the map to turn.
//
// Query parameters: `frames=A..B`, `profile=robust|assignment` and `camera=fr1` (a preset
// or fx,fy,cx,cy) prefill the controls;
// `run=bundled` starts a run on the bundled frames at once; `wait=asyncify` uses the asyncify
// build even where the browser has JSPI.
// For scripts (deploy/web/test): `document.body.dataset.state` is `ready` (waiting for the
// user), `running`, `done` or `error`; `window.wgslam` holds `{ state, error, result,
// wallSeconds, adapterName, suspensions, stackBytesMax, renders, wait }` (wait: "jspi" or
// "asyncify"; stackBytesMax: the most bytes an asyncify suspension saved, 0 with JSPI).

import { drawTrajectory } from "./plot.js";
import * as suspending from "wgslam_suspend";
import { filesOfInput, filesOfDrop } from "./picker.js";

const BUNDLED_ROOT = "assets/icl_living_room_kt2";
const $ = (id) => document.getElementById(id);
window.wgslam = { state: "loading", renders: 0 };

function setState(state, fields = {}) {
  Object.assign(window.wgslam, { state }, fields);
  document.body.dataset.state = state;
}

function say(text) {
  $("status").className = "";
  $("status").textContent = text;
}

function fail(message) {
  $("status").className = "error";
  $("status").textContent = `error: ${message}`;
  setState("error", { error: message });
}

// What the browser lacks, in the words of what to do; null when everything is there.
async function preflight() {
  if (!window.isSecureContext) {
    return (
      `this page is not a secure context (it came over plain HTTP from ${location.host}), and ` +
      "browsers offer WebGPU only to secure contexts. Open it over https://, or from " +
      "http://localhost on the machine that serves it (from another machine, forward the " +
      "port: ssh -L 8000:localhost:8000 that-machine, then http://localhost:8000/)."
    );
  }
  if (!navigator.gpu) {
    return (
      "this browser offers no WebGPU (navigator.gpu is missing). Use Chrome, Chromium or Edge " +
      "113 or later; on Linux, start Chromium with --enable-unsafe-webgpu (WebGPU is off there " +
      "by default); in Firefox, set dom.webgpu.enabled; in Safari, turn on WebGPU under " +
      "Develop > Feature Flags."
    );
  }
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) {
    return (
      "WebGPU is there but offers no GPU adapter (no usable GPU or driver, or WebGPU is " +
      "blocked for this GPU). Chromium's chrome://gpu says why; on Linux, start it with " +
      "--enable-unsafe-webgpu (with --enable-features=Vulkan for a Vulkan driver); a machine " +
      "without a GPU can use SwiftShader, Chromium's software adapter, with the same flag."
    );
  }
  const info = adapter.info;
  window.wgslam.adapterName = info
    ? [info.vendor, info.architecture, info.description].filter(Boolean).join(" ")
    : "";
  return null;
}

let wasm;
let mod;
// The data to run on: { root, files: [{ path, size }], read(path) -> Promise<Uint8Array>,
// describe }.
let data = null;
let busy = false;

async function bundled() {
  const list = await (await fetch("data/files.json")).json();
  return {
    root: BUNDLED_ROOT,
    files: list.files.map((f) => ({ path: `${BUNDLED_ROOT}/${f.path}`, size: f.size })),
    read: async (path) => {
      const response = await fetch(`data/${path.slice(BUNDLED_ROOT.length + 1)}`);
      if (!response.ok) throw new Error(`HTTP ${response.status}`);
      return new Uint8Array(await response.arrayBuffer());
    },
    describe: `the bundled ICL-NUIM frames (${list.frames} frames)`,
  };
}

// A picked or dropped folder: File objects by path; each is read when the run asks.
function folder(picked) {
  const byPath = new Map(picked.map((f) => [f.path, f.file]));
  const bytes = picked.reduce((s, f) => s + f.file.size, 0);
  const root = picked[0].path.split("/")[0];
  return {
    root,
    files: picked.map((f) => ({ path: f.path, size: f.file.size })),
    read: async (path) => {
      const file = byPath.get(path);
      if (!file) throw new Error("not among the picked files");
      return new Uint8Array(await file.arrayBuffer());
    },
    describe:
      `folder ${root}: ${picked.length} files, ${(bytes / 1e6).toFixed(1)} MB, read from your ` +
      "disk frame by frame as the run needs them (nothing is uploaded)",
  };
}

function choose(d) {
  data = d;
  $("chosen").textContent = `Data: ${d.describe}.`;
  setState("ready");
  say("ready: press Run");
}

async function main() {
  if (location.protocol === "file:") return; // index.html said why.
  say("checking the browser's WebGPU…");
  const missing = await preflight();
  if (missing) return fail(missing);
  say("loading the WebAssembly module…");
  // JSPI where the browser has it (the browser keeps suspended stacks); else the asyncify
  // build, which unwinds and rewinds its own (about half again as large, and slower).
  const wait = new URLSearchParams(location.search).get("wait") === "asyncify" || !suspending.hasJspi
    ? "asyncify"
    : "jspi";
  window.wgslam.wait = wait;
  const file = suspending.choose(wait);
  mod = await import("./pkg/wgslam.js");
  wasm = await mod.default({ module_or_path: new URL(`./pkg/${file}`, import.meta.url) });
  suspending.attach(wasm);
  mod.set_progress(onProgress);
  mod.set_frame_view(onFrame);

  const query = new URLSearchParams(location.search);
  $("frames").value = query.get("frames") ?? "";
  if (query.get("profile")) $("profile").value = query.get("profile");
  if (query.get("camera")) $("camera").value = query.get("camera");
  $("bundled").onclick = async () => choose(await bundled());
  $("folder").onchange = () => {
    try {
      choose(folder(filesOfInput($("folder").files)));
    } catch (e) {
      fail(e.message);
    }
  };
  const drop = $("drop");
  drop.addEventListener("dragover", (e) => {
    e.preventDefault();
    drop.classList.add("over");
  });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", async (e) => {
    e.preventDefault();
    drop.classList.remove("over");
    // A disabled fieldset still takes drops: not while a run reads the chosen folder.
    if (busy) return;
    try {
      choose(folder(await filesOfDrop(e.dataTransfer)));
    } catch (err) {
      fail(err.message);
    }
  });
  $("run").onclick = run;
  setupOrbit($("map"));
  $("controls").disabled = false;
  choose(await bundled());
  if (query.get("run") === "bundled") await run();
}

// `A..B` -> [A, B]; empty -> [-1, -1] (the command line's default range); else null.
function frameRange(text) {
  if (!text.trim()) return [-1, -1];
  const m = /^\s*(\d+)\s*\.\.\s*(\d+)\s*$/.exec(text);
  if (!m || Number(m[1]) > Number(m[2])) return null;
  return [Number(m[1]), Number(m[2])];
}

async function run() {
  if (busy || !data) return;
  const range = frameRange($("frames").value);
  if (!range) return fail(`frames ${JSON.stringify($("frames").value)}: want A..B (inclusive, A <= B), e.g. 0..9, or empty for all`);
  mod.clear_files();
  for (const f of data.files) mod.add_file(f.path, f.size);
  // Counted, so the page (and its test) can show how little of a folder a run reads.
  Object.assign(window.wgslam, { filesRead: 0, bytesRead: 0 });
  mod.set_reader(async (path) => {
    const bytes = await data.read(path);
    window.wgslam.filesRead += 1;
    window.wgslam.bytesRead += bytes.length;
    return bytes;
  });
  const camera = $("camera").value.trim();
  const bad = mod.configure(data.root, $("profile").value, camera);
  if (bad) return fail(bad);
  busy = true;
  $("controls").disabled = true;
  $("summary").textContent = "";
  $("downloads").textContent = "";
  drawTrajectory($("trajectory"), [], []);
  setState("running", { error: undefined, result: undefined });
  say("starting the GPU…");
  globalThis.wgslamSuspensions = 0;
  globalThis.wgslamStackBytesMax = 0;
  const t0 = performance.now();
  let rc;
  try {
    rc = await suspending.call(wasm.wgslam_web_run, range[0], range[1]);
  } finally {
    busy = false;
    $("controls").disabled = false;
  }
  const wallSeconds = (performance.now() - t0) / 1e3;
  if (rc !== 0) return fail(mod.last_error() ?? `run returned ${rc}`);
  const result = JSON.parse(mod.result_json());
  $("summary").textContent = [
    `data: ${data.describe}; layout ${result.layout}`,
    ...result.notes.map((n) => `note: ${n}`),
    intrinsicsLine(result.metrics.intrinsics, camera),
    `WebGPU adapter: ${window.wgslam.adapterName || "(unnamed)"}; ${result.key_kernels} key kernels`,
    ...result.summary,
    `read ${window.wgslam.filesRead} files, ${(window.wgslam.bytesRead / 1e6).toFixed(1)} MB of the ` +
      `${(data.files.reduce((s, f) => s + f.size, 0) / 1e6).toFixed(1)} MB listed`,
    `wall time ${wallSeconds.toFixed(1)} s in this tab; ${globalThis.wgslamSuspensions} waits ` +
      `for the GPU or a file (suspensions through ${window.wgslam.wait === "jspi" ? "JSPI" : "asyncify"}), ` +
      `${(globalThis.wgslamSuspensions / result.metrics.frames).toFixed(0)} per frame`,
  ].join("\n");
  plot(result);
  offerDownloads(result.downloads);
  say("done: turn the map with the mouse, or download the outputs below");
  setState("done", {
    result,
    wallSeconds,
    suspensions: globalThis.wgslamSuspensions,
    stackBytesMax: globalThis.wgslamStackBytesMax,
  });
}

// Which intrinsics the run used (pixels of the raw frames), and where they came from.
function intrinsicsLine(k, camera) {
  const from = camera
    ? `chosen on the page (${camera})`
    : "the folder's own (camera.json or its layout's files)";
  const n = (v) => Number(v.toFixed(3));
  return `intrinsics: fx ${n(k.fx)}, fy ${n(k.fy)}, cx ${n(k.cx)}, cy ${n(k.cy)}, ${k.width}x${k.height}; ${from}`;
}

function plot(result) {
  const aligned = result.estimate_aligned.length > 0;
  drawTrajectory($("trajectory"), aligned ? result.estimate_aligned : result.estimate, result.ground_truth);
  $("trajectory-caption").textContent = aligned
    ? "Camera path from above: ground truth (blue) and the estimate (red) after the rigid alignment of the aligned ATE."
    : "Camera path from above: the estimate (red), in the first camera's frame; the sequence has no ground truth.";
}

function offerDownloads(names) {
  const box = $("downloads");
  box.append("Download: ");
  for (const name of names) {
    const a = document.createElement("a");
    a.textContent = name;
    a.download = name;
    a.href = "#";
    a.dataset.name = name;
    // Made on first click (the mesh takes a moment), then a plain blob link.
    a.addEventListener("click", (e) => {
      if (a.href.startsWith("blob:")) return;
      e.preventDefault();
      const bytes = mod.download(name);
      if (!bytes) return fail(mod.last_error() ?? `${name}: nothing to download`);
      a.href = URL.createObjectURL(new Blob([bytes]));
      a.click();
    });
    box.append(a);
  }
}

function onProgress(done, total, points, ms, status) {
  $("progress").max = total;
  $("progress").value = done;
  say(`frame ${done} of ${total}: ${ms.toFixed(0)} ms, ${points} points, ${status}`);
}

function putRgba(canvas, width, height, rgba) {
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width;
    canvas.height = height;
  }
  const image = new ImageData(new Uint8ClampedArray(rgba.buffer, rgba.byteOffset, rgba.length), width, height);
  canvas.getContext("2d").putImageData(image, 0, 0);
}

function showMap() {
  const rgba = mod.render_rgba();
  if (rgba) putRgba($("map"), mod.view_width(), mod.view_height(), rgba);
  window.wgslam.renders += 1;
}

function onFrame(newMap) {
  const [w, h] = [mod.frame_width(), mod.frame_height()];
  putRgba($("color"), w, h, mod.frame_rgba());
  putRgba($("depth"), w, h, mod.depth_rgba());
  $("frame-caption").textContent = `The current input frame (${w}x${h}): colour`;
  if (newMap) showMap();
  // The path so far, as tracked (the run's world frame; the ground truth comes at the end).
  const flat = mod.live_path();
  const path = [];
  for (let i = 0; i + 3 < flat.length; i += 4) path.push([flat[i], flat[i + 1], flat[i + 2], flat[i + 3]]);
  if (path.length > 1) {
    drawTrajectory($("trajectory"), path, []);
    $("trajectory-caption").textContent = "Camera path so far, from above (as tracked; the ground truth is drawn at the end).";
  }
}

// The orbit: yaw and pitch (radians), zoom (distance multiple), pan (distance units).
const view = { yaw: 0, pitch: 0, zoom: 1, pan: [0, 0] };
window.wgslam.view = view;
let drawing = false;
let again = false;

// Sends the view to the module; after a run, draws it (one picture in flight at a time,
// the latest view drawn next). During a run the next map picture uses it.
async function redraw() {
  mod.set_orbit(view.yaw, view.pitch, view.zoom, view.pan[0], view.pan[1]);
  if (window.wgslam.state !== "done") return;
  if (drawing) {
    again = true;
    return;
  }
  drawing = true;
  window.wgslam.drawing = true;
  try {
    do {
      again = false;
      mod.set_orbit(view.yaw, view.pitch, view.zoom, view.pan[0], view.pan[1]);
      const rc = await suspending.call(wasm.wgslam_web_render);
      if (rc !== 0) return fail(mod.last_error() ?? "the map could not be drawn");
      showMap();
    } while (again);
  } finally {
    drawing = false;
    window.wgslam.drawing = false;
  }
}

function setupOrbit(canvas) {
  const pointers = new Map();
  let last = null;
  const spread = () => {
    const [a, b] = [...pointers.values()];
    return { d: Math.hypot(a.x - b.x, a.y - b.y), x: (a.x + b.x) / 2, y: (a.y + b.y) / 2 };
  };
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => {
    // Capture keeps a drag that leaves the canvas; a pointer the browser does not know
    // (a script's) cannot be captured, which changes nothing else.
    try {
      canvas.setPointerCapture(e.pointerId);
    } catch {}
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    last = pointers.size === 2 ? spread() : { x: e.clientX, y: e.clientY };
  });
  const up = (e) => {
    pointers.delete(e.pointerId);
    last = pointers.size === 1 ? { ...pointers.values().next().value } : null;
  };
  canvas.addEventListener("pointerup", up);
  canvas.addEventListener("pointercancel", up);
  canvas.addEventListener("pointermove", (e) => {
    if (!pointers.has(e.pointerId) || !last) return;
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    const scale = 1 / canvas.clientHeight;
    if (pointers.size === 2) {
      const now = spread();
      view.zoom *= last.d / Math.max(now.d, 1);
      view.pan[0] -= (now.x - last.x) * scale;
      view.pan[1] += (now.y - last.y) * scale;
      last = now;
    } else {
      const [dx, dy] = [e.clientX - last.x, e.clientY - last.y];
      if (e.shiftKey || e.buttons === 2) {
        view.pan[0] -= dx * scale;
        view.pan[1] += dy * scale;
      } else {
        view.yaw -= dx * Math.PI * scale;
        view.pitch = Math.max(-1.5, Math.min(1.5, view.pitch - dy * Math.PI * scale));
      }
      last = { x: e.clientX, y: e.clientY };
    }
    redraw();
  });
  canvas.addEventListener(
    "wheel",
    (e) => {
      e.preventDefault();
      view.zoom = Math.max(0.05, Math.min(20, view.zoom * Math.exp(e.deltaY * 0.001)));
      redraw();
    },
    { passive: false },
  );
  $("reset-view").onclick = () => {
    Object.assign(view, { yaw: 0, pitch: 0, zoom: 1, pan: [0, 0] });
    redraw();
  };
}

// A Rust panic traps the module; src/web leaves its message in `wgslamPanic`.
main().catch((e) => fail(globalThis.wgslamPanic ? `panic: ${globalThis.wgslamPanic}` : (e?.stack ?? String(e))));
window.addEventListener("unhandledrejection", (e) =>
  fail(globalThis.wgslamPanic ? `panic: ${globalThis.wgslamPanic}` : String(e.reason?.stack ?? e.reason)),
);
