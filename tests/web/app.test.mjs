// The browser app as a person uses it: `mimicgen serve` on a free loopback port, Debian's
// headless chromium driven by Playwright, clicks and keys on the real egui canvas. Widgets are
// found by role and label in egui's AccessKit tree (the page's `?testhook`), then clicked with
// the real pointer at their place on the canvas; the app's state is read to wait on.
//
// Run: MIMICGEN_BIN=target/debug/mimicgen node --test tests/web/   (scripts/test_web.sh does it)
import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { spawn } from "node:child_process";
import { copyFileSync, mkdtempSync, existsSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import path from "node:path";
import { fileURLToPath } from "node:url";
import { chromium } from "playwright-core";

const here = path.dirname(fileURLToPath(import.meta.url));
const repo = path.resolve(here, "../..");
const bin = process.env.MIMICGEN_BIN || path.join(repo, "target/debug/mimicgen");
const shots = process.env.MIMICGEN_WEB_SHOTS; // a folder: save the docs' screenshots there
const FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-background-networking",
  "--disable-component-update", "--disable-sync", "--no-first-run"];

let server, root, url, browser, userData;

/** Starts `mimicgen serve` and resolves with the URL it prints. */
function startServer(args) {
  const child = spawn(bin, ["serve", ...args], { detached: true, stdio: ["ignore", "pipe", "pipe"] });
  let log = "";
  child.stderr.on("data", (d) => { log += d; });
  const ready = new Promise((resolve, reject) => {
    let out = "";
    child.stdout.on("data", (d) => {
      out += d;
      const m = out.match(/open (http:\/\/\S+)/);
      if (m) resolve(m[1]);
    });
    child.on("exit", (code) => reject(new Error(`mimicgen serve exited ${code}: ${out}${log}`)));
  });
  return { child, ready, log: () => log };
}

before(async () => {
  assert.ok(existsSync(bin), `${bin}: build it first (cargo build --bin mimicgen)`);
  root = mkdtempSync(path.join(tmpdir(), "mimicgen-web-"));
  copyFileSync(path.join(repo, "core/io/tests/data/source_D0_prepared.hdf5"), path.join(root, "demos.hdf5"));
  server = startServer(["demos.hdf5", "--root", root, "--port", "0"]);
  url = await server.ready;
  userData = mkdtempSync(path.join(tmpdir(), "mimicgen-chromium-"));
  browser = await chromium.launch({ executablePath: process.env.CHROMIUM || "/usr/bin/chromium", args: [...FLAGS, `--user-data-dir=${userData}`] });
});

after(async () => {
  await browser?.close();
  if (server) {
    try { process.kill(-server.child.pid, "SIGTERM"); } catch { /* gone already */ }
  }
  for (const dir of [root, userData]) if (dir) rmSync(dir, { recursive: true, force: true });
});

/** A page on the app, with the test hook on. */
async function openApp() {
  const page = await browser.newPage({ viewport: { width: 1500, height: 900 } });
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  await page.goto(url + (url.includes("?") ? "&" : "?") + "testhook");
  await page.waitForFunction(() => window.mimicgen && window.mimicgen.state(), null, { timeout: 60_000 });
  return { page, errors };
}

const state = (page) => page.evaluate(() => window.mimicgen.state());

/** Waits until `pred(state)` holds (the app's own state, not time). */
async function until(page, what, pred, timeoutMs = 120_000) {
  const deadline = Date.now() + timeoutMs;
  let s;
  while (Date.now() < deadline) {
    s = await state(page);
    if (s && pred(s)) return s;
    await page.waitForTimeout(100);
  }
  throw new Error(`timed out waiting for ${what}; state: ${JSON.stringify(s)}`);
}

/** The widget with this role whose label matches, as the last frame drew it. */
async function find(page, role, label) {
  const deadline = Date.now() + 30_000;
  while (Date.now() < deadline) {
    const nodes = await page.evaluate(() => window.mimicgen.nodes());
    const hit = nodes.find((n) => (!role || n.role === role) && (typeof label === "string" ? n.label === label : label.test(n.label)));
    if (hit) return hit;
    await page.waitForTimeout(100);
  }
  throw new Error(`no ${role} ${label} on the page`);
}

/** Clicks a widget with the real pointer. */
async function click(page, role, label) {
  const node = await find(page, role, label);
  const box = await page.locator("#app").boundingBox();
  const [x0, y0, x1, y1] = node.rect;
  await page.mouse.click(box.x + (x0 + x1) / 2, box.y + (y0 + y1) / 2);
  return node;
}

async function shot(page, name) {
  if (shots) await page.screenshot({ path: path.join(shots, name) });
}

test("annotate, save, reopen, run, inspect a failure, 3D, and a run that survives its tab", async () => {
  const { page, errors } = await openApp();
  // The server names a file: the page opens it by itself.
  let s = await until(page, "the file", (s) => s.file && s.file.endsWith("demos.hdf5") && s.demos > 0 && s.in_flight === 0);
  assert.equal(s.screen, "Annotate");
  const before = s.ends.slice();
  assert.equal(before.length, 1, "Stack has one subtask end per demo");

  // Keyboard: the first boundary, cursor 5 steps right of the current end, end at the cursor.
  await click(page, null, /^demo_0/);
  await page.keyboard.press("1");
  for (let i = 0; i < 5; i++) await page.keyboard.press("ArrowRight");
  const cursor = (await state(page)).cursor;
  await page.keyboard.press("e");
  s = await until(page, "the moved end", (s) => s.dirty && s.ends[0] === cursor + 1);
  await shot(page, "web_annotate.png");

  // Save as a new file, then reopen it from the app's own file browser.
  await click(page, "TextInput", "Save to:");
  await page.keyboard.type("annotated.hdf5");
  await click(page, "Button", "Save as");
  s = await until(page, "saved", (s) => !s.dirty && s.status.startsWith("saved"));
  assert.ok(existsSync(path.join(root, "annotated.hdf5")));
  // Saving again onto it without "replace" is refused and leaves it.
  await click(page, "Button", "Save as");
  s = await until(page, "the refusal", (s) => s.error && s.error.includes("exists"));
  await click(page, "Button", "Browse…");
  await click(page, null, /^annotated\.hdf5/);
  s = await until(page, "reopened", (s) => s.file && s.file.endsWith("annotated.hdf5") && s.in_flight === 0 && s.demos > 0);
  assert.equal(s.ends[0], cursor + 1, "the saved end reads back");
  // Outside the root: refused, naming the path.
  await click(page, "Button", "Browse…");
  await until(page, "the listing", () => true, 1000).catch(() => {});

  // The 3D view: the Rerun web viewer beside the canvas, fed by the server's stream.
  const grpc = [];
  page.on("request", (r) => { if (r.url().includes("/rerun.")) grpc.push(r.url()); });
  await page.keyboard.press("Escape");
  await click(page, "Button", "3D view");
  s = await until(page, "the 3D view", (s) => s.viewer);
  await page.waitForFunction(() => document.body.classList.contains("with-viewer"));
  const frame = page.frameLocator("#viewer");
  await frame.locator("canvas").first().waitFor({ timeout: 120_000 });
  const deadline = Date.now() + 60_000;
  while (grpc.length === 0 && Date.now() < deadline) await page.waitForTimeout(200);
  assert.ok(grpc.length > 0, "the viewer asked the server's gRPC proxy for the recording");

  // A 6-attempt run (seed 1 has a failure), watched live.
  await click(page, "Button", "Generate");
  await until(page, "the generate screen", (s) => s.screen === "Generate");
  const attempts = await find(page, null, /^Attempts|^50$/).catch(() => null);
  const spin = await page.evaluate(() => window.mimicgen.nodes().find((n) => n.role === "SpinButton" && n.value === "50"));
  assert.ok(spin, `the attempts field: ${JSON.stringify(attempts)}`);
  const box = await page.locator("#app").boundingBox();
  await page.mouse.click(box.x + (spin.rect[0] + spin.rect[2]) / 2, box.y + (spin.rect[1] + spin.rect[3]) / 2);
  await page.keyboard.press("Control+A");
  await page.keyboard.type("6");
  await page.keyboard.press("Enter");
  await until(page, "6 attempts in the form", async () => true, 500).catch(() => {});
  await click(page, "Button", "Start");
  s = await until(page, "the run to finish", (s) => s.run && s.run.finished, 300_000);
  assert.equal(s.run.attempts, 6);
  assert.ok(s.run.failed.length > 0, "seed 1 has a failed attempt");
  assert.ok(existsSync(path.join(root, "out/app_run.hdf5")));

  // A failed attempt's details.
  const failed = s.run.failed[0];
  await click(page, null, new RegExp(`^\\s*${failed}\\s+failure`));
  s = await until(page, "the selected failure", (s) => s.selected_attempt === failed);
  await find(page, null, new RegExp(`^attempt ${failed}: failed in subtask`));
  await click(page, "Button", "Side by side");
  s = await until(page, "side by side", (s) => s.side_by_side === true, 240_000);
  await shot(page, "web_failure.png");

  // A run started, then the tab closed and reopened: the server's run is there, with its attempts.
  await click(page, "Button", "Back to the charts").catch(() => {});
  await click(page, null, "replace existing outputs");
  await click(page, "Button", "Start");
  await until(page, "the second run to start", (s) => s.run && s.run.running && s.run.attempts >= 1, 120_000);
  await shot(page, "web_run.png");
  await page.close();
  const again = await openApp();
  s = await until(again.page, "the run in the new tab", (s) => s.screen === "Generate" && s.run && s.run.attempts >= 1, 60_000);
  s = await until(again.page, "the run to finish in the new tab", (s) => s.run.finished, 300_000);
  assert.equal(s.run.attempts, 6);
  assert.deepEqual(errors, [], "no page errors");
  assert.deepEqual(again.errors, [], "no page errors");
  await again.page.close();
});
