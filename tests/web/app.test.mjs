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

let server, root, url, browser;

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
  // A plain robomimic file (robosuite's Lift demos, no datagen_info): the server prepares it.
  copyFileSync(path.join(repo, "core/io/tests/data/robosuite_lift_demo.hdf5"), path.join(root, "lift.hdf5"));
  // Two Arm Lift's bundled source demos: one view per arm.
  copyFileSync(path.join(repo, "core/sim/data/two_arm_lift_D0_source.hdf5"), path.join(root, "two_arm.hdf5"));
  server = startServer(["demos.hdf5", "--root", root, "--port", "0"]);
  url = await server.ready;
  browser = await chromium.launch({ executablePath: process.env.CHROMIUM || "/usr/bin/chromium", args: FLAGS });
});

after(async () => {
  await browser?.close();
  if (server) {
    try { process.kill(-server.child.pid, "SIGTERM"); } catch { /* gone already */ }
  }
  if (root) rmSync(root, { recursive: true, force: true });
});

/** A page on the app, with the test hook on. */
async function openApp() {
  const page = await browser.newPage({ viewport: { width: 1500, height: 900 } });
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  // Where an error came from (this page or the viewer's frame), for the failure message.
  page.on("console", (m) => { if (m.type() === "error") console.error(`console error (${m.location().url}): ${m.text().slice(0, 500)}`); });
  await page.goto(url + (url.includes("?") ? "&" : "?") + "testhook");
  await page.waitForFunction(() => window.mimicgen && window.mimicgen.state(), null, { timeout: 60_000 });
  return { page, errors };
}

const state = (page) => page.evaluate(() => window.mimicgen.state());

/** Waits until `read()` resolves to `want`. */
async function untilValue(read, want, what, timeoutMs = 30_000) {
  const deadline = Date.now() + timeoutMs;
  let got;
  while (Date.now() < deadline) {
    got = await read();
    if (got === want) return got;
    await new Promise((r) => setTimeout(r, 100));
  }
  throw new Error(`timed out waiting for ${what}: ${JSON.stringify(got)}, not ${JSON.stringify(want)}`);
}

/** Waits until `pred(state)` holds (the app's own state, not time). */
async function until(page, what, pred, timeoutMs = 120_000) {
  const deadline = Date.now() + timeoutMs;
  let s;
  while (Date.now() < deadline) {
    s = await state(page);
    if (s && pred(s)) return s;
    await page.waitForTimeout(100);
  }
  await shot(page, "timed_out.png");
  throw new Error(`timed out waiting for ${what}; state: ${JSON.stringify(s)}`);
}

/** The widget with this role whose text matches, as the last frame drew it. */
async function find(page, role, label) {
  const deadline = Date.now() + 30_000;
  let nodes = [];
  while (Date.now() < deadline) {
    nodes = await page.evaluate(() => window.mimicgen.nodes());
    // A button's text is its label; a label's text is its value.
    const text = (n) => n.label || n.value;
    const matches = (n) => (typeof label === "string" ? text(n) === label : typeof label === "function" ? label(n) : label.test(text(n)));
    const hit = nodes.find((n) => (!role || n.role === role) && matches(n));
    if (hit) return hit;
    await page.waitForTimeout(100);
  }
  await shot(page, "not_found.png");
  const seen = nodes.filter((n) => n.label || n.value).map((n) => `${n.role} ${JSON.stringify(n.label || n.value)}`);
  throw new Error(`no ${role} ${label} on the page; it has: ${seen.join(", ")}`);
}

/** Clicks a widget with the real pointer. */
async function click(page, role, label) {
  const node = await find(page, role, label);
  const box = await page.locator("#app").boundingBox();
  const [x0, y0, x1, y1] = node.rect;
  await page.mouse.click(box.x + (x0 + x1) / 2, box.y + (y0 + y1) / 2);
  return node;
}

/** Types `value` into the number field showing `current` (egui's DragValue: click, then type). */
async function setNumber(page, current, value) {
  const field = await find(page, "SpinButton", (n) => n.value === current);
  const box = await page.locator("#app").boundingBox();
  await page.mouse.click(box.x + (field.rect[0] + field.rect[2]) / 2, box.y + (field.rect[1] + field.rect[3]) / 2);
  await page.keyboard.press("Control+A");
  await page.keyboard.type(String(value));
  await page.keyboard.press("Enter");
  await find(page, "SpinButton", (n) => n.value === String(value));
}

async function shot(page, name) {
  // Generous: with the 3D view and a run going, two cores draw slowly.
  if (shots) await page.screenshot({ path: path.join(shots, name), timeout: 180_000 });
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
  // S marks where the segment of the subtask under the cursor starts (here the second's).
  for (let i = 0; i < 3; i++) await page.keyboard.press("ArrowRight");
  await page.keyboard.press("s");
  s = await until(page, "the marked start", (s) => s.starts[1] === cursor + 3);
  assert.equal(s.starts[0], null, "the first subtask's start is left to the detector");
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
  await click(page, "Button", /^annotated\.hdf5/);
  s = await until(page, "reopened", (s) => s.file && s.file.endsWith("annotated.hdf5") && s.in_flight === 0 && s.demos > 0);
  assert.equal(s.ends[0], cursor + 1, "the saved end reads back");
  assert.deepEqual(s.starts, [null, cursor + 3], "so does the marked start");
  // The 3D view: the Rerun web viewer beside the canvas, fed by the server's stream through the
  // page's own origin, with one time cursor.
  const grpc = [];
  page.on("request", (r) => { if (r.url().includes("/rerun.")) grpc.push(r.url()); });
  await page.keyboard.press("Escape");
  await click(page, "Button", "3D view");
  s = await until(page, "the 3D view", (s) => s.viewer);
  await page.waitForFunction(() => document.body.classList.contains("with-viewer"));
  const viewer = page.frames().find((f) => f.url().includes("/rerun/"));
  assert.ok(viewer, "the viewer's frame");
  const stepInViewer = () => viewer.evaluate(() => {
    const h = window._handle, rec = h && h.get_active_recording_id();
    return rec ? h.get_time_for_timeline(rec, "step") ?? null : null;
  });
  await viewer.waitForFunction(() => window._handle && window._handle.get_active_recording_id(), null, { timeout: 180_000, polling: 250 });
  assert.ok(grpc.length > 0, "the viewer read the recording through the server's gRPC proxy");
  // The app's cursor moves the viewer's time...
  s = await state(page);
  await untilValue(stepInViewer, s.cursor, "the viewer at the app's cursor");
  await click(page, null, /^step \d+ of/);
  for (let i = 0; i < 3; i++) await page.keyboard.press("ArrowLeft");
  s = await state(page);
  await untilValue(stepInViewer, s.cursor, "the viewer following the app's keys");
  // ...and scrubbing the viewer's time moves the app's cursor.
  const scrubbed = s.cursor + 7;
  await viewer.evaluate((t) => window._handle.set_time_for_timeline(window._handle.get_active_recording_id(), "step", t), scrubbed);
  s = await until(page, "the app's cursor at the viewer's time", (s) => s.cursor === scrubbed, 30_000);
  await shot(page, "web_3d.png");

  // A 6-attempt run (seed 1 has a failure), watched live.
  await click(page, "Button", "Generate");
  await until(page, "the generate screen", (s) => s.screen === "Generate");
  await setNumber(page, "50", 6);
  await click(page, "Button", "Start");
  s = await until(page, "the run to finish", (s) => s.run && s.run.finished, 300_000);
  assert.equal(s.run.planned, 6);
  assert.equal(s.run.attempts, 6);
  assert.ok(s.run.failed.length > 0, "seed 1 has a failed attempt");
  assert.ok(existsSync(path.join(root, "out/app_run.hdf5")));
  if (shots) {
    // The viewer shades itself while the run's last messages arrive: a picture once it settled.
    await page.waitForTimeout(5000);
    await shot(page, "web_run.png");
  }

  // A failed attempt's details.
  const failed = s.run.failed[0];
  await click(page, null, new RegExp(`^\\s*${failed}\\s+failure`));
  s = await until(page, "the selected failure", (s) => s.selected_attempt === failed);
  await find(page, null, new RegExp(`^attempt ${failed}: failed in subtask`));
  await click(page, "Button", "Side by side");
  s = await until(page, "side by side", (s) => s.side_by_side === true, 240_000);
  await shot(page, "web_failure.png");

  // A long run started, then its tab closed and the URL opened again: the server's run is there,
  // still going, with the attempts decided meanwhile; the new tab cancels it.
  await click(page, "Button", "Back to the charts").catch(() => {});
  await setNumber(page, "6", 2000);
  await click(page, "CheckBox", "replace existing outputs");
  await click(page, "Button", "Start");
  s = await until(page, "the second run to start", (s) => s.run && s.run.planned === 2000 && s.run.running && s.run.attempts >= 1, 120_000);
  const seen = s.run.attempts;
  await page.close();
  const again = await openApp();
  s = await until(again.page, "the run in the new tab", (s) => s.screen === "Generate" && s.run && s.run.planned === 2000 && s.run.attempts > seen, 120_000);
  assert.ok(s.run.running, "the run went on without its tab");
  await click(again.page, "Button", "Cancel");
  s = await until(again.page, "the run to stop", (s) => !s.run.running, 120_000);
  assert.ok(s.run.attempts < 2000, "cancelled before its end");
  assert.deepEqual(errors, [], "no page errors");
  assert.deepEqual(again.errors, [], "no page errors");
  await again.page.close();
});

test("a plain robomimic file: opened from the served folder, prepared, previewed, tried, saved and run", async () => {
  const { page, errors } = await openApp();
  await until(page, "the served file", (s) => s.file && s.demos > 0 && s.in_flight === 0);
  await click(page, "TextInput", "Source demos:");
  await page.keyboard.press("Control+A");
  await page.keyboard.type("lift.hdf5");
  await click(page, "Button", "Open");
  // Prepared by replay into the server's cache, named by an alias (never the server's path).
  let s = await until(page, "the prepared file", (s) => s.file && s.file.startsWith("@prepared/lift-") && s.demos === 3 && s.in_flight === 0);
  assert.ok(s.prepared_from.endsWith("lift.hdf5"), s.prepared_from);
  await click(page, "Button", "Preview");
  s = await until(page, "the preview", (s) => s.screen === "Preview" && s.preview && s.preview.task === "lift" && s.in_flight === 0);
  assert.equal(s.error, null, "no refusal");
  await click(page, "Button", "Try it");
  s = await until(page, "the tried attempt", (s) => s.preview && s.preview.executed !== null && s.in_flight === 0);
  await click(page, "TextInput", "Save to:");
  await page.keyboard.press("Control+A");
  await page.keyboard.type("lift_annotated.hdf5");
  await click(page, "Button", "Save as");
  s = await until(page, "saved", (s) => s.status.startsWith("saved"));
  assert.ok(existsSync(path.join(root, "lift_annotated.hdf5")));
  await click(page, "Button", "Generate");
  await until(page, "the generate screen", (s) => s.screen === "Generate");
  await setNumber(page, "50", 2);
  // The first test's run wrote the default output: replace it.
  if (existsSync(path.join(root, "out/app_run.hdf5"))) await click(page, "CheckBox", "replace existing outputs");
  await click(page, "Button", "Start");
  s = await until(page, "the run of the prepared file", (s) => s.run && s.run.planned === 2 && s.run.finished, 300_000);
  assert.equal(s.run.attempts, 2);
  assert.equal(s.run.error, null);
  assert.deepEqual(errors, [], "no page errors");
  await page.close();
});

test("a two-arm file: one arm's end annotated, the other kept, both saved, an attempt tried with both", async () => {
  const { page, errors } = await openApp();
  await until(page, "the served file", (s) => s.file && s.demos > 0 && s.in_flight === 0);
  await click(page, "TextInput", "Source demos:");
  await page.keyboard.press("Control+A");
  await page.keyboard.type("two_arm.hdf5");
  await click(page, "Button", "Open");
  let s = await until(page, "the two-arm file", (s) => s.file && s.file.endsWith("/two_arm.hdf5") && s.arms === 2 && s.in_flight === 0);
  const [arm0, arm1] = s.arm_ends;
  if (s.screen !== "Annotate") {
    await click(page, "Button", "Annotate");
    await until(page, "the annotate screen", (s) => s.screen === "Annotate");
  }
  await click(page, null, /^arm 1 \(robot1\)$/);
  s = await until(page, "arm 1 annotated", (s) => s.arm === 1);
  assert.deepEqual(s.ends, arm1);
  // One step per key, then E: keys are handled in order, so E puts the end where the cursor came
  // to (a key pressed while the canvas takes focus may be lost: the state says where that is).
  for (let i = 0; i < 25; i++) await page.keyboard.press("ArrowRight");
  await page.keyboard.press("e");
  s = await until(page, "arm 1's end moved to the cursor", (s) => s.ends[0] !== arm1[0] && s.ends[0] === s.cursor + 1);
  const cursor = s.cursor;
  assert.ok(cursor >= 20 && cursor <= 25, `cursor ${cursor}`);
  assert.deepEqual(s.arm_ends[0], arm0, "arm 0 keeps its own end");
  await click(page, null, /^arm 0 \(robot0\)$/);
  s = await until(page, "arm 0 annotated", (s) => s.arm === 0);
  assert.deepEqual(s.ends, arm0);
  assert.deepEqual(s.arm_ends[1], [cursor + 1]);
  await shot(page, "web_two_arm.png");
  await click(page, "TextInput", "Save to:");
  await page.keyboard.press("Control+A");
  await page.keyboard.type("two_arm_annotated.hdf5");
  await click(page, "Button", "Save as");
  s = await until(page, "saved", (s) => s.status.startsWith("saved") && s.in_flight === 0);
  assert.ok(existsSync(path.join(root, "two_arm_annotated.hdf5")));
  // The preview tries an attempt with both arms' ends and draws the lift's coordination.
  await click(page, "Button", "Preview");
  s = await until(page, "the two-arm preview", (s) => s.preview && s.preview.task === "two_arm_lift" && s.in_flight === 0);
  assert.equal(s.error, null, "no refusal");
  assert.equal(s.preview.arms, 2);
  assert.deepEqual(s.preview.ties, ["coordination"]);
  assert.notEqual(s.preview.executed, null);
  await shot(page, "web_two_arm_preview.png");
  assert.deepEqual(errors, [], "no page errors");
  await page.close();
});
