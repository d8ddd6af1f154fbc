// One click selects an object in headless Chromium, on a real capture: serve opens on
// ../shared/data/statue (the scene reconstructed as captured). On a view's photo (the editor), a
// click with the click tool draws the statue's outline as the region, which Preview masks takes.
// On the splats (the camera on one of the views), a click selects splats that lie on the statue
// there and not on the ground below it, shift-click adds, and Fill then removes every one.
import { readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import * as h from "./harness.mjs";

h.skipUnlessReady();
const statue = h.sharedScene("statue");
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

  // The editor: the view's photo, the click tool, a click inside the statue's own mask.
  await page.locator(`#strip figure[data-index="${index}"]`).click();
  await page.waitForFunction(() => document.getElementById("paint-image").complete);
  const own = await page.evaluate(async (i) => {
    const bitmap = await createImageBitmap(await (await fetch(`/api/views/${i}/mask`)).blob());
    const ctx = new OffscreenCanvas(bitmap.width, bitmap.height).getContext("2d");
    ctx.drawImage(bitmap, 0, 0);
    const d = ctx.getImageData(0, 0, bitmap.width, bitmap.height).data;
    const inside = Array.from({ length: bitmap.width * bitmap.height }, (_, k) => (d[4 * k] > 127 ? 1 : 0));
    let sx = 0, sy = 0, n = 0;
    inside.forEach((v, k) => v && ((sx += k % bitmap.width), (sy += Math.floor(k / bitmap.width)), n++));
    return { inside, width: bitmap.width, height: bitmap.height, centre: [sx / n, sy / n] };
  }, index);
  await page.locator("#pick").click();
  const paintBox = await page.locator("#paint-canvas").boundingBox();
  await page.mouse.click(paintBox.x + (own.centre[0] / own.width) * paintBox.width,
    paintBox.y + (own.centre[1] / own.height) * paintBox.height);
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const onView = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(!onView.error && onView.width === own.width && onView.height === own.height,
    `a click on the photo selects (${onView.error ?? `${onView.selected} points, ${onView.pixels} pixels`})`);
  let at = 0, both = 0;
  onView.runs.forEach((length, k) => {
    if (k % 2) for (let i = at; i < at + length; i++) both += own.inside[i];
    at += length;
  });
  const ownCount = own.inside.reduce((a, b) => a + b, 0);
  h.check(both / onView.pixels > 0.8 && both / ownCount > 0.5, `its outline on the photo is the statue's ` +
    `(precision ${(both / onView.pixels).toFixed(3)}, recall ${(both / ownCount).toFixed(3)} against the view's own mask)`);
  console.log(`measured: a click on the photo to its outline drawn ${onView.clientSeconds.toFixed(2)} s ` +
    `(server: select and carve ${onView.ms["select and carve"].toFixed(0)} ms)`);
  // One selection: `masks --click` with the same click, height and views gives the clicked view
  // the mask the page outlines (the same reconstruction, the same selection and carving).
  const [clickX, clickY] = onView.sent.clicks.split(",");
  h.run(["masks", "--scene", statue, "--view", "IMG_2707", "--click", `${clickX},${clickY}`, "--height", "128",
    "--views", "2", "--out", join(dir, "masks")]);
  const commandMask = await page.evaluate(async (b64) => {
    const bitmap = await createImageBitmap(await (await fetch(`data:image/png;base64,${b64}`)).blob());
    const ctx = new OffscreenCanvas(bitmap.width, bitmap.height).getContext("2d");
    ctx.drawImage(bitmap, 0, 0);
    const d = ctx.getImageData(0, 0, bitmap.width, bitmap.height).data;
    return Array.from({ length: bitmap.width * bitmap.height }, (_, k) => (d[4 * k] > 127 ? 1 : 0));
  }, readFileSync(join(dir, "masks", "IMG_2707.png")).toString("base64"));
  let runAt = 0, differ = 0;
  onView.runs.forEach((length, k) => {
    for (let i = runAt; i < runAt + length; i++) differ += commandMask[i] !== (k % 2);
    runAt += length;
  });
  h.check(commandMask.length === onView.width * onView.height && differ <= 0.005 * onView.pixels,
    `masks --click gives the clicked view the page's outline (${differ} of its ${onView.pixels} pixels differ)`);
  const painted = await page.evaluate(() => {
    const c = document.getElementById("paint-canvas");
    const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    for (let k = 3; k < d.length; k += 4) n += d[k] > 0;
    return n;
  });
  writeFileSync(join(dir, "outline.png"), await page.screenshot());
  console.log(`picture: ${join(dir, "outline.png")}`);
  h.check(painted === onView.pixels, `the outline is the painted region Run and Preview send (${painted} pixels)`);
  await page.locator("#preview").click();
  await page.waitForFunction(() => window.instainpaint.lastRun, null, { timeout: 300000 });
  const preview = await page.evaluate(() => window.instainpaint.lastRun);
  h.check(preview.state === "done" && Object.keys(preview.result.masks).length > 1,
    `Preview masks propagates the clicked region (${preview.state}${preview.error ? ": " + preview.error : ""})`);

  // The box tool without a segmenter: a box dragged around the statue's own mask (its bounding box
  // grown by 5 %) outlines it by GrabCut, as `masks --box` does.
  const [bx0, by0, bx1, by1] = (() => {
    let x0 = own.width, y0 = own.height, x1 = 0, y1 = 0;
    own.inside.forEach((v, k) => {
      if (!v) return;
      const x = k % own.width, y = Math.floor(k / own.width);
      [x0, y0, x1, y1] = [Math.min(x0, x), Math.min(y0, y), Math.max(x1, x + 1), Math.max(y1, y + 1)];
    });
    const [dx, dy] = [(x1 - x0) * 0.025, (y1 - y0) * 0.025];
    return [Math.max(0, x0 - dx), Math.max(0, y0 - dy), Math.min(own.width, x1 + dx), Math.min(own.height, y1 + dy)];
  })();
  await page.evaluate(() => (window.instainpaint.lastSelect = null));
  await page.locator("#photo-box").click();
  const toScreen = (x, y) => [paintBox.x + (x / own.width) * paintBox.width, paintBox.y + (y / own.height) * paintBox.height];
  await page.mouse.move(...toScreen(bx0 + 0.5, by0 + 0.5));
  await page.mouse.down();
  await page.mouse.move(...toScreen(bx1 - 0.5, by1 - 0.5), { steps: 4 });
  await page.mouse.up();
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const boxed = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(!boxed.error && boxed.how === "GrabCut in the box", `a box on the photo selects by GrabCut (${boxed.error ?? boxed.how})`);
  let boxAt = 0, boxBoth = 0;
  boxed.runs.forEach((length, k) => {
    if (k % 2) for (let i = boxAt; i < boxAt + length; i++) boxBoth += own.inside[i];
    boxAt += length;
  });
  h.check(boxBoth / boxed.pixels > 0.95 && boxBoth / ownCount > 0.9, `the box's outline is the statue's (precision ` +
    `${(boxBoth / boxed.pixels).toFixed(3)}, recall ${(boxBoth / ownCount).toFixed(3)} against the view's own mask)`);
  console.log(`measured: a box on the photo to its outline drawn ${boxed.clientSeconds.toFixed(2)} s ` +
    `(server: GrabCut ${boxed.ms.grabcut.toFixed(0)} ms)`);
  writeFileSync(join(dir, "box-outline.png"), await page.screenshot());
  console.log(`picture: ${join(dir, "box-outline.png")}`);
  h.check((await page.locator("#status").textContent()).includes("GrabCut in the box"), "the status names GrabCut");

  // The splats: the camera on that view, a click on the statue there.
  await page.evaluate(() => (window.instainpaint.lastSelect = null));
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
  writeFileSync(join(dir, "selected.png"), await page.screenshot());
  console.log(`picture: ${join(dir, "selected.png")}`);
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
