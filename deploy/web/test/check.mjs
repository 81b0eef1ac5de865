// The browser build in a real browser: serves deploy/web/dist from a local static server
// (python3 -m http.server), loads the page in headless Chromium with WebGPU, waits for the
// run, and checks what the page reports against the native run's metrics.json on the same
// frames: the same frame count, no lost frame on either side, and ATE within
// ATE_TOLERANCE_MM. Saves a screenshot of the finished page. Every request the page makes
// must go to the local server (the page fetches nothing from other hosts).
//
// node check.mjs --dist DIR --native-metrics FILE --screenshot FILE.png
//                [--frames A..B] [--chromium PATH] [--timeout-s S]

import { spawn } from "node:child_process";
import { readFileSync } from "node:fs";
import net from "node:net";
import { chromium } from "playwright-core";

// Browser (SwiftShader) against native (lavapipe), both the portable GPU kernels, each
// tracking on its own: the same tolerance as `wgslam compare --free` allows per frame
// between two backends' poses (POSE_MAX_MM in src/tools/compare/mod.rs: f32 sums in another
// order, another compiler's fused multiply-adds). The RMSE of two trajectories' errors
// differs by at most the RMSE of their difference, so poses within 0.1 mm of each other
// give ATEs within 0.1 mm (up to the rigid alignment's own small change).
const ATE_TOLERANCE_MM = 0.1;

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
    nativeMetrics: get("native-metrics"),
    screenshot: get("screenshot"),
    frames: get("frames", ""),
    chromium: get("chromium", "/usr/bin/chromium"),
    timeoutS: Number(get("timeout-s", "900")),
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

async function main() {
  const opt = args();
  const native = JSON.parse(readFileSync(opt.nativeMetrics, "utf8"));
  const port = await freePort();
  const server = spawn("python3", ["-m", "http.server", String(port), "--bind", "127.0.0.1", "--directory", opt.dist], {
    stdio: ["ignore", "ignore", "ignore"],
  });
  let browser;
  try {
    await waitForPort(port, 10_000);
    browser = await chromium.launch({
      executablePath: opt.chromium,
      headless: true,
      args: [
        "--enable-unsafe-webgpu",
        "--no-sandbox",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        "--disable-quic",
        // Every host but the local server is unresolvable.
        "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
      ],
    });
    const page = await browser.newPage({ viewport: { width: 1400, height: 1100 } });
    const origin = `http://127.0.0.1:${port}`;
    const foreign = [];
    const console_ = [];
    page.on("request", (r) => {
      if (!r.url().startsWith(origin) && !r.url().startsWith("data:") && !r.url().startsWith("blob:")) {
        foreign.push(r.url());
      }
    });
    page.on("console", (m) => console_.push(`${m.type()}: ${m.text()}`));
    page.on("pageerror", (e) => console_.push(`pageerror: ${e.message}`));
    const query = opt.frames ? `?frames=${opt.frames}` : "";
    const t0 = Date.now();
    await page.goto(`${origin}/index.html${query}`);
    try {
      await page.waitForFunction(() => ["done", "error"].includes(document.body.dataset.state), null, {
        timeout: opt.timeoutS * 1000,
        polling: 500,
      });
    } catch (e) {
      console.error(console_.join("\n"));
      throw new Error(`the page did not finish within ${opt.timeoutS} s: ${await page.textContent("#status")}`);
    }
    const pageSeconds = (Date.now() - t0) / 1000;
    await page.screenshot({ path: opt.screenshot, fullPage: true });
    const state = await page.evaluate(() => window.wgslam);
    if (state.state !== "done") {
      console.error(console_.join("\n"));
      throw new Error(`the page reports an error: ${state.error}`);
    }
    const m = state.result.metrics;
    console.log("page summary:\n  " + state.result.summary.join("\n  "));
    console.log(`page: WebGPU adapter ${state.adapterName}, ${state.result.key_kernels} key kernels; ${pageSeconds.toFixed(1)} s from load to done; ${state.suspensions} JSPI suspensions`);

    const failures = [];
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
    console.log(
      `time per frame (median): page ${(m.time_per_frame_median_s * 1e3).toFixed(1)} ms ` +
        `(${m.backend} on ${state.adapterName}), native ${(native.time_per_frame_median_s * 1e3).toFixed(1)} ms (${native.backend})`,
    );
    console.log(`map points: page ${m.map_points}, native ${native.map_points}`);
    console.log(`screenshot: ${opt.screenshot}`);
    if (failures.length) {
      for (const f of failures) console.error(`FAIL: ${f}`);
      process.exitCode = 1;
    } else {
      console.log("browser check passed");
    }
  } finally {
    if (browser) await browser.close();
    server.kill();
  }
}

main().catch((e) => {
  console.error(`FAIL: ${e?.stack ?? e}`);
  process.exitCode = 1;
});
