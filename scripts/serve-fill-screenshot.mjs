// The page as a new user sees it on a capture with splats: `serve --ply SPLATS --scene CAPTURE`,
// opened (screenshot 1), a view of the strip clicked (screenshot 2), one stroke painted over a world
// point on that view and *Fill* run (screenshot 3, the filled splats from the same camera).
//
//   node scripts/serve-fill-screenshot.mjs BIN SPLATS CAPTURE IMAGES VIEW X,Y,Z RADIUS_PX OUT_DIR
//
// With a mask, the page opens on VIEW exactly (its camera and size: ?view=I&exact=1), MASK (white =
// the object, the photo's size) is painted as the stroke, a 2D inpainter's picture of the photo
// given as the inpainted reference (else the page's built-in inpainter, or --inpainter NAME), and
// *Fill* run (screenshots 4-view.png, 5-filled.png):
//
//   node scripts/serve-fill-screenshot.mjs BIN SPLATS CAPTURE IMAGES VIEW --mask MASK
//       [--reference PICTURE | --inpainter patch|telea] OUT_DIR
import { mkdirSync, readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import * as h from "../tests/web/browser/harness.mjs";

const [, , , splats, capture, images, view, ...rest] = process.argv;
const out = rest.pop();
mkdirSync(out, { recursive: true });
h.skipUnlessReady();
if (rest[0] === "--mask") await onThePage({ width: 1500, height: 720 }, exactViewWithMask);
else await onThePage({ width: 1100, height: 650 }, strokeAndFill);

// `serve --ply SPLATS --scene CAPTURE` and a page on it, opened and ready; `walk` does the rest.
async function onThePage(viewport, walk) {
  const server = await h.serve(["--ply", splats, "--scene", capture, "--images", images, "--out", join(out, "serve")]);
  const browser = await h.browser();
  try {
    const page = await browser.newPage({ viewport });
    const errors = h.collectErrors(page);
    await page.goto(server.url);
    await page.evaluate(() => window.instainpaint.ready);
    const index = await page.evaluate((name) => window.instainpaint.info.scene.views.findIndex((v) => v.name === name), view);
    if (index < 0) throw new Error(`no view ${view} in ${capture}`);
    console.log(JSON.stringify({ ...(await walk(page, server, index)), errors }));
  } finally {
    await browser.close();
    server.stop();
  }
}

// *Fill* clicked and its job waited for: the job, or undefined when it was refused.
async function fill(page) {
  await page.locator("#fill-run").click();
  await page.waitForFunction(() => window.instainpaint.lastFill || window.instainpaint.lastRun?.state === "refused" ||
    document.getElementById("status").classList.contains("error"), null, { timeout: 600000 });
  return page.evaluate(() => window.instainpaint.lastFill);
}

// Opened, the view clicked in the strip, one round stroke over a world point, Fill.
async function strokeAndFill(page, server, index) {
  const [point, radius] = rest;
  await h.frames(page, 6);
  writeFileSync(join(out, "1-opened.png"), await page.screenshot());
  await page.locator("#strip figure").nth(index).click();
  await h.frames(page, 6);
  writeFileSync(join(out, "2-view.png"), await page.screenshot());
  await page.locator("#fill-paint").click();
  const centre = await page.evaluate((c) => window.instainpaint.screenPoint(c), point.split(",").map(Number));
  const canvas = await page.locator("#viewer canvas").first().boundingBox();
  const r = Number(radius);
  for (let dy = -r; dy <= r; dy += 6) {
    const half = Math.sqrt(Math.max(0, r * r - dy * dy));
    await page.mouse.move(canvas.x + centre[0] - half, canvas.y + centre[1] + dy);
    await page.mouse.down();
    await page.mouse.move(canvas.x + centre[0] + half, canvas.y + centre[1] + dy, { steps: 4 });
    await page.mouse.up();
  }
  const job = await fill(page);
  await h.frames(page, 6);
  writeFileSync(join(out, "3-filled.png"), await page.screenshot());
  return { fill: job?.result?.fill, seconds: job?.seconds };
}

// The view exactly, its object painted from a mask file, a 2D inpainter's picture as the
// reference (or the built-in inpainter named), Fill.
async function exactViewWithMask(page, server, index) {
  const option = (name) => (rest.indexOf(name) >= 0 ? rest[rest.indexOf(name) + 1] : undefined);
  const [mask, picture, inpainter] = [option("--mask"), option("--reference"), option("--inpainter")];
  await page.goto(`${server.url.replace(/\/?(\?.*)?$/, "")}/?view=${index}&exact=1`);
  await page.evaluate(() => window.instainpaint.ready);
  await page.locator("#fill-paint").click();
  await h.frames(page, 6);
  writeFileSync(join(out, "4-view.png"), await page.locator("#viewer canvas").first().screenshot());
  // The mask onto the paint canvas (its alpha is the stroke), scaled to the canvas's size.
  const painted = await page.evaluate(async (url) => {
    const image = await createImageBitmap(await (await fetch(url)).blob());
    const canvas = document.getElementById("fill-canvas");
    const scratch = new OffscreenCanvas(canvas.width, canvas.height).getContext("2d");
    scratch.drawImage(image, 0, 0, canvas.width, canvas.height);
    const from = scratch.getImageData(0, 0, canvas.width, canvas.height).data;
    const ctx = canvas.getContext("2d");
    const to = ctx.createImageData(canvas.width, canvas.height);
    let count = 0;
    for (let k = 0; k < from.length; k += 4)
      if (from[k] > 0) { to.data[k] = 255; to.data[k + 3] = 160; count++; }
    ctx.putImageData(to, 0, 0);
    return { count, width: canvas.width, height: canvas.height };
  }, `data:image/png;base64,${readFileSync(mask).toString("base64")}`);
  if (picture) await page.locator("#fill-reference").setInputFiles(picture);
  if (inpainter) await page.locator("#fill-inpainter").selectOption(inpainter);
  const job = await fill(page);
  await page.locator("#fill-paint").click();  // the stroke's canvas off: the filled view alone
  await h.frames(page, 6);
  writeFileSync(join(out, "5-filled.png"), await page.locator("#viewer canvas").first().screenshot());
  return { painted, fill: job?.result?.fill, seconds: job?.clientSeconds, state: await page.locator("#status").textContent() };
}
