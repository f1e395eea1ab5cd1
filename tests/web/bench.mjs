// The browser app's figures for BENCHMARKS.md: bundle size, time to the first frame and to the
// first file drawn, WebSocket round trips, and the app's own drawing time per frame while a run
// goes. `mimicgen serve` on a free loopback port, Debian's headless chromium (software WebGL).
//
//   bash scripts/build_web.sh && cargo build --release --bin mimicgen
//   MIMICGEN_BIN=$CARGO_TARGET_DIR/release/mimicgen node tests/web/bench.mjs [--pages 5] [--trips 300] [--run 200]
//
// Prints JSON. Not a test: nothing here is asserted.
import { spawn } from "node:child_process";
import { copyFileSync, mkdtempSync, rmSync, statSync } from "node:fs";
import { homedir, tmpdir } from "node:os";
import path from "node:path";
import { fileURLToPath } from "node:url";
import { parseArgs } from "node:util";
import { chromium } from "playwright-core";

const here = path.dirname(fileURLToPath(import.meta.url));
const repo = path.resolve(here, "../..");
const { values: args } = parseArgs({
  options: { pages: { type: "string", default: "5" }, trips: { type: "string", default: "300" }, run: { type: "string", default: "200" } },
});
const bin = process.env.MIMICGEN_BIN || path.join(repo, "target/release/mimicgen");
const web = process.env.MIMICGEN_WEB_DIR || path.join(process.env.MIMICGEN_CACHE || path.join(homedir(), ".cache/mimicgen"), "web");

const quantile = (xs, q) => {
  const s = [...xs].sort((a, b) => a - b);
  return s.length ? s[Math.min(s.length - 1, Math.floor(q * s.length))] : null;
};
const summary = (xs) => ({ n: xs.length, p50: quantile(xs, 0.5), p95: quantile(xs, 0.95), max: quantile(xs, 1) });
const round = (o) => JSON.parse(JSON.stringify(o, (_, v) => (typeof v === "number" ? Math.round(v * 100) / 100 : v)));

const root = mkdtempSync(path.join(tmpdir(), "mimicgen-bench-web-"));
copyFileSync(path.join(repo, "core/io/tests/data/source_D0_prepared.hdf5"), path.join(root, "demos.hdf5"));
const server = spawn(bin, ["serve", "demos.hdf5", "--root", root, "--port", "0", "--no-viewer"], { detached: true, stdio: ["ignore", "pipe", "inherit"] });
const url = await new Promise((resolve, reject) => {
  let out = "";
  server.stdout.on("data", (d) => {
    out += d;
    const m = out.match(/open (http:\/\/\S+)/);
    if (m) resolve(m[1]);
  });
  server.on("exit", (code) => reject(new Error(`mimicgen serve exited ${code}`)));
});
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  args: ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--no-first-run"],
});
const result = {};
try {
  const size = (name) => statSync(path.join(web, name)).size / 1e6;
  result.bundle_mb = { wasm: size("mimicgen_web_bg.wasm"), wasm_gzip: size("mimicgen_web_bg.wasm.gz"), js: size("mimicgen_web.js") };

  // A fresh page (nothing cached) to the app's first frame, and to the named file's demos drawn.
  const first = [], opened = [];
  for (let i = 0; i < Number(args.pages); i++) {
    const context = await browser.newContext({ viewport: { width: 1280, height: 800 } });
    const page = await context.newPage();
    const t0 = Date.now();
    await page.goto(url + "?testhook");
    await page.waitForFunction(() => window.mimicgen && window.mimicgen.state(), null, { polling: 5, timeout: 60_000 });
    first.push(Date.now() - t0);
    await page.waitForFunction(() => window.mimicgen.state().demos > 0, null, { polling: 5, timeout: 60_000 });
    opened.push(Date.now() - t0);
    await context.close();
  }
  result.first_frame_ms = summary(first);
  result.file_drawn_ms = summary(opened);

  // Request to reply through the server's backend (a directory listing), from the page's own
  // socket, one at a time.
  const context = await browser.newContext({ viewport: { width: 1280, height: 800 } });
  const page = await context.newPage();
  await page.goto(url + "?testhook");
  await page.waitForFunction(() => window.mimicgen && window.mimicgen.state() && window.mimicgen.state().demos > 0, null, { timeout: 60_000 });
  result.round_trip_ms = summary(await page.evaluate(async (n) => {
    const ws = new WebSocket(`ws://${location.host}/ws`);
    await new Promise((r) => (ws.onopen = r));
    const times = [];
    for (let id = 1; id <= n; id++) {
      const t0 = performance.now();
      const got = new Promise((resolve) => {
        ws.onmessage = (e) => { if (JSON.parse(e.data).id === id) resolve(); };
      });
      ws.send(JSON.stringify({ id, request: { ListDir: { path: "." } } }));
      await got;
      times.push(performance.now() - t0);
    }
    ws.close();
    return times;
  }, Number(args.trips)));

  // The app's drawing per frame on the generate screen while a 1-worker run goes.
  const nodes = () => page.evaluate(() => window.mimicgen.nodes());
  const click = async (pred) => {
    const n = (await nodes()).find(pred);
    const box = await page.locator("#app").boundingBox();
    await page.mouse.click(box.x + (n.rect[0] + n.rect[2]) / 2, box.y + (n.rect[1] + n.rect[3]) / 2);
  };
  await click((n) => n.role === "Button" && n.label === "Generate");
  await page.waitForFunction(() => window.mimicgen.nodes().some((n) => n.role === "SpinButton" && n.value === "50"));
  await click((n) => n.role === "SpinButton" && n.value === "50");
  await page.keyboard.press("Control+A");
  await page.keyboard.type(args.run);
  await page.keyboard.press("Enter");
  await page.evaluate(() => window.mimicgen.frames());
  await click((n) => n.role === "Button" && n.label === "Start");
  const t0 = Date.now();
  await page.waitForFunction(() => { const r = window.mimicgen.state().run; return r && r.finished; }, null, { polling: 200, timeout: 600_000 });
  const seconds = (Date.now() - t0) / 1000;
  const frames = await page.evaluate(() => window.mimicgen.frames());
  const run = await page.evaluate(() => window.mimicgen.state().run);
  result.run = { attempts: run.attempts, successes: run.successes, seconds, attempts_per_s: run.attempts / seconds, frames_per_s: frames.length / seconds, frame_ms: summary(frames) };
  await context.close();
} finally {
  await browser.close();
  try { process.kill(-server.pid, "SIGTERM"); } catch { /* gone */ }
  rmSync(root, { recursive: true, force: true });
}
console.log(JSON.stringify(round(result), null, 2));
