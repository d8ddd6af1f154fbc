// What the browser tests share: the instainpaint CLI, a running `serve`, headless Debian
// Chromium (software WebGL) through playwright-core, and console-error collection.
// Exit code 77 (ctest: skipped) when Chromium or playwright-core is missing.
import { spawn, execFileSync } from "node:child_process";
import { existsSync, mkdtempSync } from "node:fs";
import { createRequire } from "node:module";
import { tmpdir } from "node:os";
import { join, resolve } from "node:path";

export const cli = resolve(process.argv[2] ?? "build/instainpaint");
export const chromiumPath = process.env.CHROMIUM ?? "/usr/bin/chromium";
// INSTAINPAINT_MEASURE=1: also take the page's timings (load to first frame over an emulated
// link, frame rates), which the tests only print: a benchmark's work, kept out of CI's runs
// (scripts/measure-page.sh).
export const measure = process.env.INSTAINPAINT_MEASURE === "1";
const require = createRequire(resolve("web/package.json"));

export function skipUnlessReady() {
  if (!existsSync(chromiumPath)) {
    console.log(`skipped: no ${chromiumPath} (make deps installs Debian's chromium)`);
    process.exit(77);
  }
  try {
    require.resolve("playwright-core");
  } catch {
    console.log("skipped: no web/node_modules/playwright-core (make deps runs npm ci in web/)");
    process.exit(77);
  }
}

// A real capture of ../shared/data (or $INSTAINPAINT_SHARED/data), or a skip naming it.
export function sharedScene(name) {
  const dir = resolve(process.env.INSTAINPAINT_SHARED ?? "../shared", "data", name);
  if (!existsSync(dir)) {
    console.log(`skipped: no ${dir} (the real capture this test clicks on)`);
    process.exit(77);
  }
  return dir;
}

export const scratch = (tag) => mkdtempSync(join(tmpdir(), `instainpaint-${tag}-`));

export function run(args) {
  return execFileSync(cli, args, { encoding: "utf8", stdio: ["ignore", "pipe", "pipe"] });
}

// A small synthetic room with an object and the default model's Gaussians of it (object kept).
export function roomWithGaussians(dir) {
  run(["synth", "--out", join(dir, "rooms"), "--scenes", "1", "--seed", "3", "--views", "6", "--test-views", "1",
    "--width", "96", "--height", "64", "--object", "procedural", "--degrade", "none"]);
  const scene = join(dir, "rooms", "scene_000");
  run(["infer", "--scene", scene, "--height", "64", "--keep-object", "--out", join(dir, "infer")]);
  return { scene, ply: join(dir, "infer", "gaussians.ply") };
}

// `instainpaint serve` on a free loopback port; resolves once it listens with
//   url      the address it prints, token included (what a user opens),
//   base     that address without the token, token  the token,
//   page(q)  the printed address with more URL parameters q ("view=1&exact=1"),
//   get(p)   fetch of path p from Node with the token header (a script's way).
export function serve(args) {
  const child = spawn(cli, ["serve", "--port", "0", ...args], { stdio: ["ignore", "pipe", "pipe"] });
  let log = "";
  child.stderr.on("data", (d) => (log += d));
  return new Promise((resolveUrl, reject) => {
    let out = "";
    child.stdout.on("data", (d) => {
      out += d;
      const m = out.match(/open ((http:\/\/[^ ]+\/)\?token=([\w-]+))/);
      if (m)
        resolveUrl({
          url: m[1],
          base: m[2],
          token: m[3],
          page: (query) => `${m[1]}&${query}`,
          get: (path) => fetch(new URL(path, m[2]), { headers: { "X-Instainpaint-Token": m[3] } }),
          stop: () => child.kill("SIGTERM"),
          log: () => log,
        });
    });
    child.on("exit", (code) => reject(new Error(`serve exited with ${code}: ${log}`)));
  });
}

export async function browser() {
  const { chromium } = require("playwright-core");
  return chromium.launch({
    executablePath: chromiumPath,
    args: ["--headless=new", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox"],
  });
}

// Console errors and uncaught exceptions of a page.
export function collectErrors(page) {
  const errors = [];
  page.on("console", (m) => m.type() === "error" && errors.push(`console: ${m.text()}`));
  page.on("pageerror", (e) => errors.push(`page: ${e.message}`));
  return errors;
}

// Has the viewer draw `count` more frames (it draws on demand) and waits for them.
export async function frames(page, count) {
  const target = await page.evaluate((n) => {
    window.instainpaint.invalidate(n);
    return window.instainpaint.frames + n;
  }, count);
  await page.waitForFunction((n) => window.instainpaint.frames >= n, target, { timeout: 120000 });
}

// Waits until the viewer's picture is final (window.instainpaint.settled): at least one frame
// drawn, Spark's sort of it done (in a worker) and its order drawn (the page asks for that frame
// itself). On a loaded machine a fixed number of frames was once not enough (CI, the edit's
// masked PSNR measured on a half-drawn picture); with software WebGL each frame is about 0.5 s.
export async function settled(page) {
  await frames(page, 1);
  await page.waitForFunction(() => window.instainpaint.settled(), null, { timeout: 120000, polling: 50 });
}

// A screenshot of `locator` once the picture has settled, checked: one more frame and its
// screenshot must be the same (at most `tries` times). The frame-rate line over the canvas is
// hidden in them: its number changes with every frame.
export async function settledScreenshot(page, locator, tries = 10) {
  const shoot = () => locator.screenshot({ style: "#hud { visibility: hidden !important; }" });
  await settled(page);
  let shot = await shoot();
  for (let i = 0; i < tries; ++i) {
    await settled(page);
    const next = await shoot();
    if (next.equals(shot)) return next;
    shot = next;
  }
  return shot;
}

// The share of the viewer's pixels that are not the white background (runs in the page:
// page.evaluate(h.drawnFraction)).
export function drawnFraction() {
  const c = document.querySelector("#viewer canvas");
  const ctx = Object.assign(document.createElement("canvas"), { width: c.width, height: c.height }).getContext("2d");
  ctx.drawImage(c, 0, 0);
  const d = ctx.getImageData(0, 0, c.width, c.height).data;
  let drawn = 0;
  for (let k = 0; k < d.length; k += 4) if (d[k] < 250 || d[k + 1] < 250 || d[k + 2] < 250) drawn++;
  return drawn / (d.length / 4);
}

// Each line says when it was checked (seconds since the test started): a slow test's log
// shows where its time went.
const started = performance.now();
const elapsed = () => `${((performance.now() - started) / 1000).toFixed(1)} s`;
export function check(condition, message) {
  if (!condition) {
    console.error(`FAILED (${elapsed()}): ${message}`);
    process.exitCode = 1;
  } else {
    console.log(`ok (${elapsed()}): ${message}`);
  }
}
