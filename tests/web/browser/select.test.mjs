// One click selects an object in headless Chromium, on the splats of a real capture: serve opens
// on ../shared/data/statue (the scene reconstructed as captured), the camera on one of its views;
// a click on the statue selects splats that lie on the statue there and not on the ground below
// it, shift-click adds, and Fill then removes every selected splat.
import { existsSync } from "node:fs";
import { join, resolve } from "node:path";
import * as h from "./harness.mjs";

h.skipUnlessReady();
const statue = resolve(process.env.INSTAINPAINT_SHARED ?? "../shared", "data", "statue");
if (!existsSync(statue)) {
  console.log(`skipped: no ${statue} (the real capture this test clicks on)`);
  process.exit(77);
}
const dir = h.scratch("select");
const server = await h.serve(["--scene", statue, "--height", "128", "--views", "2", "--out", join(dir, "serve")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
  const errors = h.collectErrors(page);
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  const index = await page.evaluate(() => window.instainpaint.info.scene.views.findIndex((v) => v.name === "IMG_2707"));
  h.check(index >= 0, "the statue's view IMG_2707 is listed");
  await page.evaluate((i) => window.instainpaint.jumpToView(i), index);
  await page.locator("#fill-click").click();

  // The statue's own mask on that view, carried to the view on screen (same vertical field of
  // view, centred): as a grid of the canvas's pixels, and two points well inside it.
  const truth = await page.evaluate(async (i) => {
    const view = window.instainpaint.info.scene.views[i];
    const canvas = document.getElementById("fill-canvas");
    const bitmap = await createImageBitmap(await (await fetch(`/api/views/${i}/mask`)).blob());
    const s = canvas.height / view.height;
    const ctx = new OffscreenCanvas(canvas.width, canvas.height).getContext("2d");
    ctx.drawImage(bitmap, canvas.width / 2 - (view.width / 2) * s, 0, view.width * s, view.height * s);
    const d = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
    const inside = Array.from({ length: canvas.width * canvas.height }, (_, k) => (d[4 * k] > 127 ? 1 : 0));
    // The deepest pixel inside (farthest from the outline, a 1-2 chamfer), and one a third of the way up.
    const w = canvas.width, hgt = canvas.height, depth = inside.map((v) => (v ? 1e9 : 0));
    for (let y = 0; y < hgt; y++)
      for (let x = 0; x < w; x++) {
        const k = y * w + x;
        if (depth[k]) depth[k] = Math.min(depth[k], y ? depth[k - w] + 1 : 1, x ? depth[k - 1] + 1 : 1);
      }
    for (let y = hgt - 1; y >= 0; y--)
      for (let x = w - 1; x >= 0; x--) {
        const k = y * w + x;
        if (depth[k]) depth[k] = Math.min(depth[k], y < hgt - 1 ? depth[k + w] + 1 : 1, x < w - 1 ? depth[k + 1] + 1 : 1);
      }
    let best = 0;
    depth.forEach((v, k) => v > depth[best] && (best = k));
    const rows = inside.reduce((r, v, k) => (v ? [Math.min(r[0], Math.floor(k / w)), Math.max(r[1], Math.floor(k / w))] : r), [hgt, 0]);
    let upper = -1;
    const y = Math.round(rows[0] + (rows[1] - rows[0]) / 3);
    for (let x = 0, most = 0; x < w; x++) if (depth[y * w + x] > most) [most, upper] = [depth[y * w + x], y * w + x];
    const rect = canvas.getBoundingClientRect();
    const toClient = (k) => [rect.x + ((k % w) + 0.5) * (rect.width / w), rect.y + (Math.floor(k / w) + 0.5) * (rect.height / hgt)];
    return { inside, width: w, bottom: rows[1], clicks: [toClient(best), toClient(upper)] };
  }, index);
  h.check(truth.inside.some((v) => v), "the statue's mask shows on screen");

  // Where the selection is drawn (the server's runs) against the statue's mask.
  const agreement = (selection) => {
    let at = 0, both = 0, drawn = 0, below = 0;
    selection.runs.forEach((length, k) => {
      if (k % 2)
        for (let i = at; i < at + length; i++) {
          drawn++;
          both += truth.inside[i];
          below += Math.floor(i / selection.width) > truth.bottom + 0.02 * selection.height;
        }
      at += length;
    });
    return { precision: both / drawn, below: below / drawn, drawn };
  };
  await page.mouse.click(...truth.clicks[0]);
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const one = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(!one.error && one.selected > 0 && one.selected < one.total / 4, `a click selects some of the splats (${one.error ?? `${one.selected} of ${one.total}`})`);
  const first = agreement(one);
  h.check(first.precision > 0.8, `what the click selects lies on the statue (${(100 * first.precision).toFixed(1)} % of ${first.drawn} pixels)`);
  h.check(first.below < 0.02, `and not on the ground below it (${(100 * first.below).toFixed(1)} %)`);
  console.log(`measured: click to the drawn selection ${one.clientSeconds.toFixed(2)} s on ${one.total} splats ` +
    `(server: read ${one.ms.read.toFixed(0)} ms, select ${one.ms.select.toFixed(0)} ms, draw ${one.ms.draw.toFixed(0)} ms)`);
  const shown = await page.locator("#fill-result").textContent();
  h.check(shown.includes(`selected ${one.selected} of ${one.total} splats`), `the counts are shown (${shown})`);

  await page.evaluate(() => (window.instainpaint.lastSelect = null));
  await page.keyboard.down("Shift");
  await page.mouse.click(...truth.clicks[1]);
  await page.keyboard.up("Shift");
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const two = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(two.clicks === 2 && two.selected >= one.selected, `shift-click adds to the selection (${one.selected} -> ${two.selected})`);
  h.check(agreement(two).precision > 0.8, `still on the statue (${(100 * agreement(two).precision).toFixed(1)} %)`);

  await page.locator("#fill-run").click();
  await page.waitForFunction(() => window.instainpaint.lastFill || document.getElementById("status").classList.contains("error"),
    null, { timeout: 300000 });
  const fill = await page.evaluate(() => window.instainpaint.lastFill);
  h.check(fill?.state === "done" && fill.result.fill.removed === two.selected && fill.result.fill.added > 0,
    `Fill removes every selected splat and fills the hole (${JSON.stringify(fill?.result?.fill ?? await page.locator("#status").textContent())})`);
  h.check(errors.length === 0, `no console errors ${JSON.stringify(errors)}`);
} finally {
  await browser.close();
  server.stop();
}
