// The browser build in a real browser, used as a user would: serves deploy/web/dist from a
// local static server (python3 -m http.server), loads the page in headless Chromium with
// WebGPU, picks a sequence folder through the page's folder picker, sets the frame range,
// presses Run, waits, downloads the outputs by clicking their links and compares them with
// the native run's on the same folder and frames (ATE within ATE_TOLERANCE_MM, map points
// within MAP_POINTS_TOLERANCE, the mesh has triangles), turns the map by dragging the mouse
// and checks the picture changed, and checks the error texts of a page without WebGPU, of
// a page that is not a secure context and of a page opened from disk. A browser without
// JSPI (WebAssembly.promising and WebAssembly.Suspending removed before the page runs:
// Chromium 156 has no switch that takes JSPI away) runs the same folder through the
// asyncify build and must download the same trajectory.tum and map.ply bytes. Every request
// must go to the local server. Saves screenshots into --shots.
//
// node check.mjs --dist DIR --folder DIR --frames A..B --native DIR --shots DIR
//                [--chromium PATH] [--timeout-s S]

import { spawn } from "node:child_process";
import { mkdirSync, readFileSync, writeFileSync } from "node:fs";
import net from "node:net";
import path from "node:path";
import { chromium } from "playwright-core";

// Browser (SwiftShader) against native (lavapipe), both the portable GPU kernels, each
// tracking on its own: the same tolerance as `wgslam compare --free` allows per frame
// between two backends' poses (POSE_MAX_MM in src/tools/compare/mod.rs: f32 sums in another
// order, another compiler's fused multiply-adds). The RMSE of two trajectories' errors
// differs by at most the RMSE of their difference, so poses within 0.1 mm of each other
// give ATEs within 0.1 mm (up to the rigid alignment's own small change).
const ATE_TOLERANCE_MM = 0.1;
// Map sizes: a fusion decision on a knife edge (which surfel a pixel merges into) flips on
// ~0.5 % of pixels between two GPUs' legal arithmetic (STYLE.md, the H200 lessons); 1 %
// allows that and catches a lost or doubled frame (~5-10 % of a short run's map).
const MAP_POINTS_TOLERANCE = 0.01;
// Turning the view by a sixth of a turn moves most of the picture: at least this fraction
// of the map canvas's pixels must change (a view that ignores the drag changes none).
const MIN_CHANGED_PIXELS = 0.1;

function args() {
  const a = process.argv.slice(2);
  const get = (name, fallback) => {
    const i = a.indexOf(`--${name}`);
    if (i >= 0 && i + 1 < a.length) return a[i + 1];
    if (fallback === undefined) throw new Error(`missing --${name}`);
    return fallback;
  };
  return {
    dist: get("dist"),
    folder: get("folder"),
    frames: get("frames"),
    native: get("native"),
    shots: get("shots"),
    chromium: get("chromium", "/usr/bin/chromium"),
    timeoutS: Number(get("timeout-s", "600")),
    // A TUM folder without intrinsics, run with the camera typed on the page (a preset or
    // fx,fy,cx,cy), against the native run with the same --camera / --intrinsics.
    cameraFolder: get("camera-folder", ""),
    cameraSetting: get("camera-setting", ""),
    cameraFrames: get("camera-frames", "0..4"),
    cameraNative: get("camera-native", ""),
  };
}

async function freePort() {
  return new Promise((resolve, reject) => {
    const s = net.createServer();
    s.on("error", reject);
    s.listen(0, "127.0.0.1", () => {
      const { port } = s.address();
      s.close(() => resolve(port));
    });
  });
}

async function waitForPort(port, ms) {
  const end = Date.now() + ms;
  while (Date.now() < end) {
    const ok = await new Promise((resolve) => {
      const c = net.connect(port, "127.0.0.1", () => {
        c.end();
        resolve(true);
      });
      c.on("error", () => resolve(false));
    });
    if (ok) return;
    await new Promise((r) => setTimeout(r, 100));
  }
  throw new Error(`the static server did not listen on port ${port}`);
}

const BASE_FLAGS = [
  "--no-sandbox",
  "--disable-background-networking",
  "--disable-component-update",
  "--disable-sync",
  "--no-first-run",
  "--disable-quic",
  // Every host but the local server is unresolvable; wgslam.test is the local server under
  // another name (a page that is not a secure context).
  "--host-resolver-rules=MAP wgslam.test 127.0.0.1, MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
];

// The vertex count of a PLY file's header.
function plyCount(bytes, element) {
  const head = bytes.subarray(0, 2048).toString("latin1");
  const m = new RegExp(`element ${element} (\\d+)`).exec(head);
  return m ? Number(m[1]) : NaN;
}

async function settled(page, timeoutS, states) {
  await page.waitForFunction((s) => s.includes(document.body.dataset.state), states, {
    timeout: timeoutS * 1000,
    polling: 250,
  });
  // The state from the page's body: a page whose module never loaded (file://) has no
  // window.wgslam.
  return page.evaluate(() => ({
    ...window.wgslam,
    state: document.body.dataset.state,
    status: document.getElementById("status").textContent,
  }));
}

// The map canvas's pixels.
async function mapPixels(page) {
  return page.evaluate(() => {
    const c = document.getElementById("map");
    return Array.from(c.getContext("2d").getImageData(0, 0, c.width, c.height).data);
  });
}

// The fraction of pixels whose colour differs between two RGBA pictures of one size.
function changedFraction(before, after) {
  let changed = 0;
  for (let i = 0; i < before.length; i += 4) {
    if (before[i] !== after[i] || before[i + 1] !== after[i + 1] || before[i + 2] !== after[i + 2]) changed += 1;
  }
  return changed / (before.length / 4);
}

// What a page says when WebGPU or its conditions are missing.
async function errorText(browser, url, init) {
  const page = await browser.newPage();
  if (init) await page.addInitScript(init);
  await page.goto(url);
  const s = await settled(page, 60, ["error", "ready"]);
  await page.close();
  return s;
}

async function main() {
  const opt = args();
  mkdirSync(opt.shots, { recursive: true });
  const native = JSON.parse(readFileSync(path.join(opt.native, "metrics.json"), "utf8"));
  const nativePoints = plyCount(readFileSync(path.join(opt.native, "map.ply")), "vertex");
  const port = await freePort();
  const server = spawn("python3", ["-m", "http.server", String(port), "--bind", "127.0.0.1", "--directory", opt.dist], {
    stdio: ["ignore", "ignore", "ignore"],
  });
  const failures = [];
  const browsers = [];
  try {
    await waitForPort(port, 10_000);
    const origin = `http://127.0.0.1:${port}`;
    const browser = await chromium.launch({
      executablePath: opt.chromium,
      headless: true,
      args: ["--enable-unsafe-webgpu", ...BASE_FLAGS],
    });
    browsers.push(browser);
    const context = await browser.newContext({ viewport: { width: 1400, height: 1200 }, acceptDownloads: true });
    const page = await context.newPage();
    const foreign = [];
    const console_ = [];
    page.on("request", (r) => {
      if (!r.url().startsWith(origin) && !r.url().startsWith("data:") && !r.url().startsWith("blob:")) {
        foreign.push(r.url());
      }
    });
    page.on("console", (m) => console_.push(`${m.type()}: ${m.text()}`));
    page.on("pageerror", (e) => console_.push(`pageerror: ${e.message}`));
    await page.goto(`${origin}/index.html`);
    let s = await settled(page, 120, ["ready", "error"]);
    if (s.state !== "ready") throw new Error(`the page did not get ready: ${s.status}`);

    // As a user: the folder picker, the frame range, Run.
    await page.setInputFiles("#folder", opt.folder);
    await page.fill("#frames", opt.frames);
    const chosen = await page.textContent("#chosen");
    console.log(`page: ${chosen}`);
    const t0 = Date.now();
    await page.click("#run");
    await page.waitForFunction(() => document.body.dataset.state === "running");
    // The live view mid-run (after the first map picture; the run may also have ended).
    await page.waitForFunction(
      () => window.wgslam.renders >= 1 || document.body.dataset.state !== "running",
      null,
      { timeout: opt.timeoutS * 1000, polling: 100 },
    );
    await page.screenshot({ path: path.join(opt.shots, "page-running.png"), fullPage: true });
    try {
      s = await settled(page, opt.timeoutS, ["done", "error"]);
    } catch (e) {
      console.error(console_.join("\n"));
      throw new Error(`the page did not finish within ${opt.timeoutS} s: ${await page.textContent("#status")}`);
    }
    const pageSeconds = (Date.now() - t0) / 1000;
    await page.screenshot({ path: path.join(opt.shots, "page.png"), fullPage: true });
    if (s.state !== "done") {
      console.error(console_.join("\n"));
      throw new Error(`the page reports an error: ${s.error}`);
    }
    const m = s.result.metrics;
    console.log("page summary:\n  " + (await page.textContent("#summary")).split("\n").join("\n  "));
    console.log(
      `page: WebGPU adapter ${s.adapterName}, ${s.result.key_kernels} key kernels; ` +
        `${pageSeconds.toFixed(1)} s from Run to done; read ${s.filesRead} files (${(s.bytesRead / 1e6).toFixed(1)} MB); ` +
        `${s.renders} map pictures during the run`,
    );
    if (s.renders < 1) failures.push("no map picture during the run");

    // The downloads, by clicking their links.
    const got = {};
    for (const name of ["trajectory.tum", "map.ply", "metrics.json", "frames.json", "mesh.ply"]) {
      got[name] = await downloaded(page, name, path.join(opt.shots, `download-${name}`));
    }
    if (s.wait !== "jspi") failures.push(`the page waited through ${s.wait}, not JSPI, in a browser with JSPI`);
    const metricsFile = JSON.parse(got["metrics.json"].toString("utf8"));
    if (JSON.stringify(metricsFile) !== JSON.stringify(m)) failures.push("metrics.json differs from the page's metrics");
    const tumLines = got["trajectory.tum"].toString("utf8").split("\n").filter((l) => l && !l.startsWith("#"));
    if (tumLines.length !== m.frames - m.tracking.lost) {
      failures.push(`trajectory.tum has ${tumLines.length} poses for ${m.frames} frames (${m.tracking.lost} lost)`);
    }
    const pagePoints = plyCount(got["map.ply"], "vertex");
    const meshFaces = plyCount(got["mesh.ply"], "face");
    const frames = JSON.parse(got["frames.json"].toString("utf8"));
    console.log(
      `downloads: trajectory.tum ${tumLines.length} poses, map.ply ${pagePoints} points, ` +
        `frames.json ${frames.length} frames, mesh.ply ${plyCount(got["mesh.ply"], "vertex")} vertices ${meshFaces} triangles`,
    );
    if (frames.length !== m.frames) failures.push(`frames.json has ${frames.length} frames, metrics ${m.frames}`);
    if (!(meshFaces > 0)) failures.push("mesh.ply has no triangles");

    if (foreign.length) failures.push(`the page fetched from other hosts: ${foreign.join(", ")}`);
    if (m.frames !== native.frames || m.first_frame !== native.first_frame || m.last_frame !== native.last_frame) {
      failures.push(`frames ${m.first_frame}..${m.last_frame} (${m.frames}) in the page, ${native.first_frame}..${native.last_frame} (${native.frames}) natively`);
    }
    for (const [who, mm] of [["page", m], ["native", native]]) {
      if (mm.tracking.lost !== 0) failures.push(`${who}: ${mm.tracking.lost} frame(s) lost`);
      if (!mm.accuracy) failures.push(`${who}: no ATE (no ground truth?)`);
    }
    if (m.accuracy && native.accuracy) {
      const web = m.accuracy.ate_rmse_aligned_m * 1e3;
      const nat = native.accuracy.ate_rmse_aligned_m * 1e3;
      const diff = Math.abs(web - nat);
      console.log(
        `ATE RMSE (aligned): page ${web.toFixed(4)} mm, native ${nat.toFixed(4)} mm, ` +
          `|difference| ${diff.toFixed(4)} mm (tolerance ${ATE_TOLERANCE_MM} mm)`,
      );
      if (!(diff <= ATE_TOLERANCE_MM)) failures.push(`ATE differs by ${diff.toFixed(4)} mm > ${ATE_TOLERANCE_MM} mm`);
    }
    const rel = Math.abs(pagePoints - nativePoints) / nativePoints;
    console.log(
      `map points: page map.ply ${pagePoints}, native map.ply ${nativePoints}, relative difference ` +
        `${(rel * 100).toFixed(3)} % (tolerance ${MAP_POINTS_TOLERANCE * 100} %)`,
    );
    if (!(rel <= MAP_POINTS_TOLERANCE)) failures.push(`map sizes differ by ${(rel * 100).toFixed(2)} %`);
    console.log(
      `time per frame (median): page ${(m.time_per_frame_median_s * 1e3).toFixed(1)} ms ` +
        `(${m.backend} on ${s.adapterName}), native ${(native.time_per_frame_median_s * 1e3).toFixed(1)} ms (${native.backend})`,
    );

    // Turn the map.
    const fraction = await dragMap(page);
    console.log(`orbit: a drag changed ${(fraction * 100).toFixed(1)} % of the map's pixels (at least ${MIN_CHANGED_PIXELS * 100} %)`);
    if (!(fraction >= MIN_CHANGED_PIXELS)) failures.push(`the drag changed only ${(fraction * 100).toFixed(1)} % of the map`);
    await page.screenshot({ path: path.join(opt.shots, "page-turned.png"), fullPage: true });

    // Two fingers on a touch screen: spreading them zooms in (pointer events as a touch
    // screen sends them; headless Chromium has no multi-touch input of its own).
    const box = await page.locator("#map").boundingBox();
    const [x0, y0] = [box.x + box.width / 2, box.y + box.height / 2];
    const beforePinch = await mapPixels(page);
    const pinchRenders = await page.evaluate(() => window.wgslam.renders);
    await page.evaluate(({ x, y }) => {
      const c = document.getElementById("map");
      const send = (type, id, dx) =>
        c.dispatchEvent(
          new PointerEvent(type, { pointerId: id, pointerType: "touch", isPrimary: id === 1, clientX: x + dx, clientY: y, buttons: type === "pointerup" ? 0 : 1, bubbles: true }),
        );
      send("pointerdown", 1, -20);
      send("pointerdown", 2, 20);
      for (const d of [30, 45, 60]) {
        send("pointermove", 1, -d);
        send("pointermove", 2, d);
      }
      send("pointerup", 1, -60);
      send("pointerup", 2, 60);
    }, { x: x0, y: y0 });
    await page.waitForFunction((n) => window.wgslam.renders > n && !window.wgslam.drawing, pinchRenders, {
      timeout: 60_000,
      polling: 100,
    });
    const pinchFraction = changedFraction(beforePinch, await mapPixels(page));
    const zoom = await page.evaluate(() => window.wgslam.view.zoom);
    console.log(`pinch: zoom ${zoom.toFixed(3)} (below 1 is closer), ${(pinchFraction * 100).toFixed(1)} % of the map's pixels changed`);
    if (!(zoom < 1)) failures.push(`spreading two fingers did not zoom in (zoom ${zoom})`);
    if (!(pinchFraction >= MIN_CHANGED_PIXELS)) failures.push(`the pinch changed only ${(pinchFraction * 100).toFixed(1)} % of the map`);

    // A folder in no layout: the command line's words, from the same code.
    const junk = path.join(opt.shots, "not-a-dataset");
    mkdirSync(junk, { recursive: true });
    writeFileSync(path.join(junk, "notes.txt"), "no frames here\n");
    await page.setInputFiles("#folder", junk);
    await page.click("#run");
    const bad = await settled(page, 60, ["error"]);
    console.log(`a folder in no layout: ${bad.status.slice(0, 160)}…`);
    if (!bad.status.includes("not a dataset in any layout wgslam reads")) {
      failures.push(`a folder in no layout: not the command line's error: ${bad.status}`);
    }

    if (opt.cameraFolder) await checkCamera(page, opt, failures);

    await checkWithoutJspi(browser, origin, opt, got, failures);

    // Pages that cannot run: not a secure context (the local server under another name),
    // opened from disk, a browser with WebGPU off (Debian's Chromium without
    // --enable-unsafe-webgpu: navigator.gpu is there, requestAdapter gives null; measured
    // the same with --disable-webgpu), and a browser without WebGPU at all (navigator.gpu
    // removed before the page runs: no Chromium flag takes it away).
    const insecure = await errorText(browser, `http://wgslam.test:${port}/index.html`);
    const fromDisk = await errorText(browser, `file://${path.resolve(opt.dist, "index.html")}`);
    const plain = await chromium.launch({ executablePath: opt.chromium, headless: true, args: BASE_FLAGS });
    browsers.push(plain);
    const noAdapter = await errorText(plain, `${origin}/index.html`);
    const removeGpu = () => Object.defineProperty(Navigator.prototype, "gpu", { get: () => undefined });
    const noWebGpu = await errorText(plain, `${origin}/index.html`, removeGpu);
    const shot = await plain.newPage();
    await shot.goto(`${origin}/index.html`);
    await settled(shot, 60, ["error", "ready"]);
    await shot.screenshot({ path: path.join(opt.shots, "page-no-adapter.png") });
    for (const [what, s2, want] of [
      ["not a secure context", insecure, ["not a secure context", "http://localhost"]],
      ["opened from disk", fromDisk, ["file://", "http.server"]],
      ["no adapter", noAdapter, ["no GPU adapter", "--enable-unsafe-webgpu"]],
      ["no WebGPU", noWebGpu, ["offers no WebGPU", "Chrome, Chromium or Edge 113"]],
    ]) {
      console.log(`${what}: ${s2.status}`);
      if (s2.state !== "error") failures.push(`${what}: the page did not report an error (${s2.state})`);
      for (const w of want) if (!s2.status.includes(w)) failures.push(`${what}: no "${w}" in ${JSON.stringify(s2.status)}`);
      if (s2.status.includes("install a Vulkan driver") || s2.status.includes("--backend cpu")) {
        failures.push(`${what}: the command line's advice in the page: ${s2.status}`);
      }
    }
    console.log(`screenshots: ${opt.shots}/page-running.png, page.png, page-turned.png, page-no-adapter.png`);
    if (failures.length) {
      for (const f of failures) console.error(`FAIL: ${f}`);
      process.exitCode = 1;
    } else {
      console.log("browser check passed");
    }
  } finally {
    for (const b of browsers) await b.close();
    server.kill();
  }
}

// Drags across a sixth of the map canvas's height (a sixth of a turn), waits until every
// picture of the drag is drawn (the page draws the latest view after the one in flight),
// and returns the fraction of the map's pixels that changed.
async function dragMap(page) {
  const before = await mapPixels(page);
  const renders = await page.evaluate(() => window.wgslam.renders);
  const box = await page.locator("#map").boundingBox();
  const [x0, y0] = [box.x + box.width / 2, box.y + box.height / 2];
  await page.mouse.move(x0, y0);
  await page.mouse.down();
  await page.mouse.move(x0 + box.height / 6, y0 + box.height / 24, { steps: 4 });
  await page.mouse.up();
  await page.waitForFunction((n) => window.wgslam.renders > n && !window.wgslam.drawing, renders, {
    timeout: 60_000,
    polling: 100,
  });
  return changedFraction(before, await mapPixels(page));
}

// Clicks the page's download link for `name`, saves the file as `file` and returns its bytes.
async function downloaded(page, name, file) {
  const [download] = await Promise.all([
    page.waitForEvent("download", { timeout: 120_000 }),
    page.click(`#downloads a[data-name="${name}"]`),
  ]);
  await download.saveAs(file);
  return readFileSync(file);
}

// A browser without JSPI: the page takes the asyncify build and runs the same folder and
// frames as the main run, whose downloads are `got`. The module, the adapter and the data
// are the same, and asyncify changes only how a wait returns to the event loop, so the
// trajectory and the map must be the same bytes.
async function checkWithoutJspi(browser, origin, opt, got, failures) {
  const context = await browser.newContext({ viewport: { width: 1400, height: 1200 }, acceptDownloads: true });
  const page = await context.newPage();
  await page.addInitScript(() => {
    delete WebAssembly.promising;
    delete WebAssembly.Suspending;
  });
  await page.goto(`${origin}/index.html`);
  const ready = await settled(page, 120, ["ready", "error"]);
  if (ready.state !== "ready") {
    failures.push(`without JSPI: the page did not get ready: ${ready.status}`);
    return;
  }
  await page.setInputFiles("#folder", opt.folder);
  await page.fill("#frames", opt.frames);
  const t0 = Date.now();
  await page.click("#run");
  const s = await settled(page, opt.timeoutS, ["done", "error"]);
  if (s.state !== "done") {
    failures.push(`without JSPI: the page reports an error: ${s.status}`);
    return;
  }
  console.log(
    `without JSPI: waited through ${s.wait}, ${s.suspensions} suspensions (at most ` +
      `${s.stackBytesMax} bytes of saved locals), ` +
      `${((Date.now() - t0) / 1000).toFixed(1)} s from Run to done, ` +
      `${(s.result.metrics.time_per_frame_median_s * 1e3).toFixed(1)} ms/frame median`,
  );
  if (s.wait !== "asyncify") failures.push(`without JSPI: the page waited through ${s.wait}`);
  if (!(s.stackBytesMax > 0)) failures.push("without JSPI: no suspension unwound the stack");
  for (const name of ["trajectory.tum", "map.ply"]) {
    const bytes = await downloaded(page, name, path.join(opt.shots, `download-asyncify-${name}`));
    const same = Buffer.compare(bytes, got[name]) === 0;
    console.log(`without JSPI: ${name} ${same ? "is the same bytes as" : "DIFFERS from"} the JSPI run's`);
    if (!same) failures.push(`without JSPI: ${name} differs from the JSPI run's`);
  }
  // A drag after the run draws through the other entry point that waits.
  const fraction = await dragMap(page);
  console.log(`without JSPI: a drag changed ${(fraction * 100).toFixed(1)} % of the map's pixels`);
  if (!(fraction >= MIN_CHANGED_PIXELS)) failures.push(`without JSPI: the drag changed only ${(fraction * 100).toFixed(1)} % of the map`);
  await page.screenshot({ path: path.join(opt.shots, "page-asyncify.png"), fullPage: true });
  await context.close();
}

// A TUM folder without intrinsics: without a camera the page asks for one in its own
// words; with the camera typed in its box it runs, says which intrinsics it used, and
// gives the native run's ATE (the same tolerance as the main run).
async function checkCamera(page, opt, failures) {
  await page.setInputFiles("#folder", opt.cameraFolder);
  await page.fill("#frames", opt.cameraFrames);
  await page.fill("#camera", "");
  await page.click("#run");
  const asked = await settled(page, 60, ["error", "done"]);
  console.log(`TUM folder, no camera: ${asked.status.slice(0, 200)}`);
  if (!asked.status.includes("choose the camera on the page")) {
    failures.push(`TUM folder without a camera: the page did not ask for one: ${asked.status}`);
  }
  await page.fill("#camera", opt.cameraSetting);
  await page.click("#run");
  const s = await settled(page, opt.timeoutS, ["done", "error"]);
  if (s.state !== "done") {
    failures.push(`TUM folder with camera ${opt.cameraSetting}: ${s.status}`);
    return;
  }
  const summary = await page.textContent("#summary");
  const line = summary.split("\n").find((l) => l.startsWith("intrinsics:")) ?? "";
  console.log(`TUM folder with camera ${opt.cameraSetting}: ${line}`);
  if (!line.includes(`chosen on the page (${opt.cameraSetting})`)) {
    failures.push(`the summary does not say which intrinsics were used: ${JSON.stringify(line)}`);
  }
  await page.screenshot({ path: path.join(opt.shots, "page-camera.png"), fullPage: true });
  const native = JSON.parse(readFileSync(path.join(opt.cameraNative, "metrics.json"), "utf8"));
  const m = s.result.metrics;
  if (JSON.stringify(m.intrinsics) !== JSON.stringify(native.intrinsics)) {
    failures.push(`intrinsics: page ${JSON.stringify(m.intrinsics)}, native ${JSON.stringify(native.intrinsics)}`);
  }
  if (!m.accuracy || !native.accuracy) {
    failures.push("TUM folder with a camera: no ATE (no ground truth?)");
    return;
  }
  const [web, nat] = [m.accuracy.ate_rmse_aligned_m * 1e3, native.accuracy.ate_rmse_aligned_m * 1e3];
  const diff = Math.abs(web - nat);
  console.log(
    `TUM folder with camera ${opt.cameraSetting}, frames ${opt.cameraFrames}: ATE page ${web.toFixed(4)} mm ` +
      `(${m.accuracy.frames_without_pose} without a pose), native ${nat.toFixed(4)} mm ` +
      `(${native.accuracy.frames_without_pose} without), |difference| ${diff.toFixed(4)} mm`,
  );
  if (!(diff <= ATE_TOLERANCE_MM)) failures.push(`camera run: ATE differs by ${diff.toFixed(4)} mm > ${ATE_TOLERANCE_MM} mm`);
}

main().catch((e) => {
  console.error(`FAIL: ${e?.stack ?? e}`);
  process.exitCode = 1;
});
