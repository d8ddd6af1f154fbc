// Remove and fill on splats alone (serve --splats FILE, no capture) in headless Chromium: the
// panel offers it; a box placed around the object hides it at once (Spark's edit), Fill runs the
// server's job and the filled splats replace the old ones; a stroke painted over the object on
// the view on screen fills as well, with the view saved for a 2D inpainter and its picture given
// back as the reference (the hole takes its colours). The filled scene, rendered from a held-out camera of the
// room, shows the room behind the object better than the scene with the object did.
import { readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import * as h from "./harness.mjs";

h.skipUnlessReady();
const dir = h.scratch("fill");
h.run(["synth", "--out", join(dir, "rooms"), "--scenes", "1", "--seed", "5", "--views", "8", "--test-views", "1",
  "--width", "96", "--height", "64", "--object", "procedural", "--degrade", "none", "--save-gaussians", "--no-depth"]);
const room = join(dir, "rooms", "scene_000");
const splats = join(room, "scene.ply");
const bounds = JSON.parse(readFileSync(join(room, "synth.json"), "utf8")).object_bounds;
// 128 rows: at 64 the network's splats of a hole this small leave gaps (the white below shows).
const server = await h.serve(["--splats", splats, "--height", "128", "--views", "3", "--out", join(dir, "serve")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 900, height: 600 } });
  const errors = h.collectErrors(page);
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  h.check(await page.locator("#fill-panel").isVisible(), "the remove-and-fill panel is offered for splats alone");
  const listed = await page.locator("#plys").textContent();
  h.check(listed.includes("scene.ply"), `the splats are listed (${listed})`);

  // The box around the object: the splats inside are hidden at once.
  const shot = async (name) => {
    const file = join(dir, name);
    writeFileSync(file, await h.settledScreenshot(page, page.locator("#viewer canvas").first()));
    return file;
  };
  const before = await shot("before.png");
  const size = 2.2 * bounds.radius;
  await page.evaluate(([c, s]) => window.instainpaint.setFillBox(c, [s, s, s]), [bounds.centre, size]);
  const hidden = await shot("preview.png");
  const preview = JSON.parse(h.run(["metrics", before, hidden, "--json"]));
  h.check(preview.psnr !== "inf" && preview.psnr < 60, `the preview hides the box's splats (PSNR to before ${preview.psnr})`);

  await page.locator("#fill-run").click();
  await page.waitForFunction(() => window.instainpaint.lastFill, null, { timeout: 300000 });
  const fill = await page.evaluate(() => window.instainpaint.lastFill);
  h.check(fill.state === "done" && fill.result.fill.removed > 0 && fill.result.fill.added > 0,
    `the box's splats were removed and the hole filled (${JSON.stringify(fill.result.fill)})`);
  h.check(await page.evaluate(() => window.instainpaint.loadedUrl) === fill.result.splats, "the filled splats are on screen");
  const report = await page.evaluate(async (url) => (await fetch(url)).json(), fill.result.fill.report);
  h.check(report.inpainter === "ns", `without a reference the page fills with Navier-Stokes by default (${report.inpainter})`);
  const downloads = await page.evaluate(() => [...document.querySelectorAll("#downloads a")].map((a) => a.getAttribute("href")));
  h.check(downloads.some((d) => d.endsWith(".spz?download=1")) && downloads.some((d) => d.endsWith(".sog?download=1")),
    `downloads offer PLY, SPZ and SOG (${downloads})`);
  console.log(`measured: Fill (box) to filled splats on screen ${fill.clientSeconds.toFixed(2)} s (server ` +
    `${fill.seconds.toFixed(2)} s; CPU, 128 rows)`);

  // Seen from the room's held-out camera: the filled scene against the room without the object,
  // inside the object's mask, beside the scene with the object.
  const maskedPsnr = (ply, tag) => {
    h.run(["render", "--ply", ply, "--scene", room, "--test-views", "--no-video", "--out", join(dir, tag)]);
    return JSON.parse(h.run(["metrics", join(dir, tag, "rgb", "0000.png"), join(room, "images_4", "test_000.png"),
      "--mask", join(room, "images_4", "test_label", "test_000.png"), "--json"])).masked_psnr;
  };
  const job = fill.result.splats.match(/\/api\/jobs\/(\d+)\//)[1];
  const withObject = maskedPsnr(splats, "with-object");
  const filled = maskedPsnr(join(dir, "serve", "jobs", job, "gaussians.ply"), "filled");
  console.log(`masked PSNR against the object-free held-out view: with the object ${withObject.toFixed(2)} dB, ` +
    `filled ${filled.toFixed(2)} dB`);
  h.check(filled > withObject + 1, "the filled scene shows the room where the object was");

  // A stroke over the object on the view on screen, on the original splats.
  await page.locator("#before").click();
  await page.locator("#fill-paint").click();
  const centre = await page.evaluate((c) => window.instainpaint.screenPoint(c), bounds.centre);
  const canvas = await page.locator("#fill-canvas").boundingBox();
  const r = 0.04 * canvas.width;
  for (let dy = -r; dy <= r; dy += r / 3) {
    await page.mouse.move(canvas.x + centre[0] - r, canvas.y + centre[1] + dy);
    await page.mouse.down();
    await page.mouse.move(canvas.x + centre[0] + r, canvas.y + centre[1] + dy, { steps: 4 });
    await page.mouse.up();
  }
  // Save view and mask: two PNGs of the canvas's size, for a 2D inpainter.
  const savedFiles = [];
  page.on("download", (d) => savedFiles.push(d));
  await page.locator("#fill-save").click();
  for (let t = 0; savedFiles.length < 2 && t < 100; t++) await page.waitForTimeout(100);
  const canvasSize = await page.evaluate(() => [document.getElementById("fill-canvas").width, document.getElementById("fill-canvas").height]);
  const saved = {};
  for (const d of savedFiles) {
    const png = readFileSync(await d.path());
    saved[d.suggestedFilename()] = [png.readUInt32BE(16), png.readUInt32BE(20)];  // IHDR's width and height
  }
  h.check(JSON.stringify(saved) === JSON.stringify({ "view.png": canvasSize, "mask.png": canvasSize }),
    `save view and mask gives view.png and mask.png at the canvas's ${canvasSize} (${JSON.stringify(saved)})`);
  // Their inpainted view as the reference: magenta, which the room has nowhere, at the view's size.
  const magenta = await page.evaluate(async ([w, hgt]) => {
    const c = new OffscreenCanvas(w, hgt);
    const ctx = c.getContext("2d");
    ctx.fillStyle = "#ff00ff";
    ctx.fillRect(0, 0, w, hgt);
    const bytes = new Uint8Array(await (await c.convertToBlob({ type: "image/png" })).arrayBuffer());
    return btoa(String.fromCharCode(...bytes));
  }, canvasSize);
  await page.locator("#fill-reference").setInputFiles({ name: "inpainted.png", mimeType: "image/png", buffer: Buffer.from(magenta, "base64") });
  await page.evaluate(() => (window.instainpaint.lastFill = null));
  await page.locator("#fill-run").click();
  await page.waitForFunction(() => window.instainpaint.lastFill || window.instainpaint.lastRun?.state === "refused" ||
    document.getElementById("status").classList.contains("error"), null, { timeout: 300000 });
  const stroke = await page.evaluate(() => window.instainpaint.lastFill);
  h.check(stroke?.state === "done" && stroke.result.fill.removed > 0 && stroke.result.fill.added > 0,
    `the stroke's splats were removed and filled (${JSON.stringify(stroke?.result?.fill ?? await page.locator("#status").textContent())})`);
  // Seen from the same view, the hole shows the reference's colours.
  await h.settled(page);
  const pixel = await page.evaluate(([x, y]) => {
    const c = document.querySelector("#viewer canvas");
    const ctx = Object.assign(document.createElement("canvas"), { width: c.width, height: c.height }).getContext("2d");
    ctx.drawImage(c, 0, 0);
    const s = c.width / c.getBoundingClientRect().width;
    return Array.from(ctx.getImageData(Math.round(x * s), Math.round(y * s), 1, 1).data.slice(0, 3));
  }, centre);
  h.check(pixel[0] > 150 && pixel[2] > 150 && pixel[1] < 100, `the filled hole shows the inpainted reference's magenta (${pixel})`);
  h.check(errors.length === 0, `no console errors ${JSON.stringify(errors)}`);
} finally {
  await browser.close();
  server.stop();
}
