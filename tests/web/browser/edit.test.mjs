// A whole edit in headless Chromium: pick a view, paint the object with the mouse, Run; the
// server propagates the mask and runs the default model, the new splats replace the old ones
// on screen, and where the object was the page now shows the room behind it.
import { writeFileSync } from "node:fs";
import { join } from "node:path";
import * as h from "./harness.mjs";

h.skipUnlessReady();
const dir = h.scratch("edit");
const { scene, ply } = h.roomWithGaussians(dir);
const server = await h.serve(["--scene", scene, "--ply", ply, "--height", "64", "--out", join(dir, "serve")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 1100, height: 700 } });
  const errors = h.collectErrors(page);
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  await page.locator('#strip figure[data-index="2"]').click();
  await page.waitForFunction(() => document.getElementById("paint-image").complete);

  // The object's box in view 2, from the scene's own mask, in the painting's screen pixels.
  const box = await page.evaluate(async () => {
    const bitmap = await createImageBitmap(await (await fetch("/api/views/2/mask")).blob());
    const ctx = new OffscreenCanvas(bitmap.width, bitmap.height).getContext("2d");
    ctx.drawImage(bitmap, 0, 0);
    const d = ctx.getImageData(0, 0, bitmap.width, bitmap.height).data;
    let x0 = Infinity, y0 = Infinity, x1 = -1, y1 = -1;
    for (let y = 0; y < bitmap.height; y++)
      for (let x = 0; x < bitmap.width; x++)
        if (d[4 * (y * bitmap.width + x)] > 127) [x0, y0, x1, y1] = [Math.min(x0, x), Math.min(y0, y), Math.max(x1, x), Math.max(y1, y)];
    return { x0, y0, x1, y1, width: bitmap.width, height: bitmap.height };
  });
  h.check(box.x1 >= 0, `view 2 shows the object (mask box ${JSON.stringify(box)})`);
  const paint = await page.locator("#paint-canvas").boundingBox();
  const sx = paint.width / box.width, sy = paint.height / box.height;
  await page.locator("#size").fill("30");
  // Strokes across the box, row by row.
  for (let y = box.y0; y <= box.y1 + 1; y += 2) {
    await page.mouse.move(paint.x + box.x0 * sx, paint.y + y * sy);
    await page.mouse.down();
    await page.mouse.move(paint.x + (box.x1 + 1) * sx, paint.y + y * sy, { steps: 4 });
    await page.mouse.up();
  }

  await page.locator("#run").click();
  await page.waitForFunction(() => window.instainpaint.lastRun, null, { timeout: 300000 });
  const run = await page.evaluate(() => window.instainpaint.lastRun);
  h.check(run.state === "done", `the edit ran (${run.state}${run.error ? ": " + run.error : ""})`);
  h.check(/^\/api\/jobs\/\d+\/gaussians\.ply$/.test(run.result.ply), `the new PLY is served (${run.result.ply})`);
  h.check(/^\/api\/jobs\/\d+\/gaussians\.spz$/.test(run.result.spz), `and its SPZ (${run.result.spz})`);
  h.check(/^\/api\/jobs\/\d+\/gaussians\.compressed\.ply$/.test(run.result.splats),
    `the page gets the compressed PLY (${run.result.splats})`);
  h.check(await page.evaluate(() => window.instainpaint.loadedUrl) === run.result.splats, "the compressed PLY is displayed");
  const stageRows = await page.evaluate(() => [...document.querySelectorAll("#stages tr")].map((r) => r.textContent));
  h.check(stageRows.some((r) => r.startsWith("network")) && stageRows.some((r) => r.startsWith("page: splats loaded")),
    `where the time went is shown under the result (${stageRows.length} rows)`);
  const downloads = await page.evaluate(() => [...document.querySelectorAll("#downloads a")].map((a) => a.getAttribute("href")));
  const sog = run.result.ply.replace(/\.ply$/, ".sog");
  h.check(downloads.includes(`${run.result.ply}?download=1`) && downloads.includes(`${run.result.spz}?download=1`) &&
    downloads.includes(`${sog}?download=1`), `downloads offer PLY, SPZ and SOG (${downloads})`);
  const sogBytes = await page.evaluate(async (url) => new Uint8Array(await (await fetch(url)).arrayBuffer()).slice(0, 2), sog);
  h.check(sogBytes[0] === 0x50 && sogBytes[1] === 0x4b, "the SOG download is a zip bundle");
  console.log(`measured: Run to new splats on screen ${run.clientSeconds.toFixed(2)} s (server ${run.seconds.toFixed(2)} s; ` +
    `CPU, ${run.result.gaussians} Gaussians at 64 rows)`);
  const overlays = await page.evaluate(() => [...document.querySelectorAll("#strip canvas.overlay")].filter((c) => {
    const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
    for (let k = 3; k < d.length; k += 4) if (d[k] > 0) return true;
    return false;
  }).length);
  h.check(overlays >= 5, `the propagated masks are shown over the views (${overlays} of 6)`);

  // Export: the orbit video of the splats on screen, linked when done.
  await page.locator("#video").click();
  await page.waitForFunction(() => document.querySelector("#exports a"), null, { timeout: 300000 });
  const video = await page.evaluate(() => document.querySelector("#exports a").getAttribute("href"));
  const mp4 = await server.get(video);
  h.check(mp4.status === 200 && mp4.headers.get("content-type") === "video/mp4", `the orbit video is served (${video})`);
  await page.close();

  // View 2 exactly, before (the PLY with the object) and after (the edit's): inside the
  // object's mask the page now shows the room without the object (the synthetic room's clean
  // image), where before it showed the object.
  const maskedPsnr = async (ply, tag) => {
    const exact = await browser.newPage();
    exact.on("pageerror", (e) => errors.push(`page: ${e.message}`));
    await exact.goto(server.page(`view=2&exact=1&ply=${encodeURIComponent(ply)}`), { timeout: 120000 });
    await exact.evaluate(() => window.instainpaint.ready);
    const shot = join(dir, `${tag}.png`);
    writeFileSync(shot, await h.settledScreenshot(exact, exact.locator("canvas").first()));
    await exact.close();
    const m = JSON.parse(h.run(["metrics", shot, join(scene, "clean", "view_002.png"), "--mask",
      join(scene, "images_4", "label", "view_002.png"), "--json"]));
    return m.masked_psnr;
  };
  const before = await maskedPsnr("0", "before"), after = await maskedPsnr(run.result.ply, "after");
  console.log(`masked PSNR against the object-free view: before ${before.toFixed(2)} dB, after ${after.toFixed(2)} dB`);
  // Measured +2.8 dB: the default model at 64 rows fills the hole with a blurred floor, and
  // the object in `before` is itself a blurred novel view.
  h.check(after > before + 1.5, "the painted object's splats are gone (the region now shows the room behind it)");
  h.check(errors.length === 0, `no console errors ${JSON.stringify(errors)}`);
} finally {
  await browser.close();
  server.stop();
}
