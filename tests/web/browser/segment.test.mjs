// The page's clicks with a segmenter (serve --segmenter), in headless Chromium on the statue with
// the small MobileSAM-layout fixture of tests/segment (seeded random weights): a click on a view's
// photo draws the segmenter's outline at once, the same mask `instainpaint segment` gives for the
// point the page sent; alt-click adds a point that is not the object; a box dragged with the box
// tool gives the CLI's --box mask, and a shift-click adds a point to it; a click on the splats
// selects those under the segmenter's outline of their render, and the later click on the same
// view runs the decoder alone (no encoding).
import { readFileSync } from "node:fs";
import { join, resolve } from "node:path";
import * as h from "./harness.mjs";

h.skipUnlessReady();
const statue = h.sharedScene("statue");
const fixture = resolve("tests/segment/fixture/mobile_sam_small.pt");
const dir = h.scratch("segment");
const server = await h.serve(["--scene", statue, "--height", "128", "--views", "2", "--segmenter", fixture,
  "--precision", "fp32", "--out", join(dir, "serve")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
  const errors = h.collectErrors(page);
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  const info = await page.evaluate(() => window.instainpaint.info);
  h.check(info.segmenter?.network?.startsWith("MobileSAM TinyViT"), `the page knows the segmenter (${JSON.stringify(info.segmenter)})`);
  // It says which networks it runs, and the command that brings the absent ones (LaMa, the released checkpoint).
  const networks = await page.locator("#networks").innerText();
  h.check(networks.includes("click: MobileSAM TinyViT") && networks.includes("hole: OpenCV Navier-Stokes") &&
    networks.includes("not in the cache: LaMa, the released checkpoint; instainpaint models get big-lama instainpaint"), `the page names its networks (${networks})`);
  const index = info.scene.views.findIndex((v) => v.name === "IMG_2707");

  // The editor: the photo, the click tool, a click.
  await page.locator(`#strip figure[data-index="${index}"]`).click();
  await page.waitForFunction(() => document.getElementById("paint-image").complete);
  await page.locator("#pick").click();
  const box = await page.locator("#paint-canvas").boundingBox();
  await page.mouse.click(box.x + 0.6 * box.width, box.y + 0.68 * box.height);
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const one = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(!one.error && one.how === "segmenter" && one.pixels > 0 && one.scores.length === 3,
    `a click on the photo is outlined by the segmenter (${one.error ?? `${one.how}, ${one.pixels} pixels`})`);
  console.log(`measured: click to outline ${one.clientSeconds.toFixed(2)} s (server: encode ${one.ms.encode.toFixed(0)} ms, ` +
    `decode ${one.ms.decode.toFixed(0)} ms)`);

  // The CLI's answer for the very point the page sent.
  const photo = join(statue, "images_2", "IMG_2707.png");
  h.run(["segment", "--segmenter", fixture, "--image", photo, "--click", one.sent.clicks, "--precision", "fp32",
    "--out", join(dir, "cli.png"), "--json"]);
  // How many pixels of a selection's outline differ from a mask PNG the CLI wrote (-1: other sizes).
  const pixelsDiffering = async (png, selection) => {
    const cli = await page.evaluate(async (bytes) => {
      const bitmap = await createImageBitmap(new Blob([new Uint8Array(bytes)], { type: "image/png" }));
      const ctx = new OffscreenCanvas(bitmap.width, bitmap.height).getContext("2d");
      ctx.drawImage(bitmap, 0, 0);
      const d = ctx.getImageData(0, 0, bitmap.width, bitmap.height).data;
      return Array.from({ length: bitmap.width * bitmap.height }, (_, k) => (d[4 * k] > 127 ? 1 : 0));
    }, [...readFileSync(png)]);
    if (cli.length !== selection.width * selection.height) return -1;
    let at = 0, differ = 0;
    const drawn = new Uint8Array(cli.length);
    selection.runs.forEach((length, k) => {
      if (k % 2) drawn.fill(1, at, at + length);
      at += length;
    });
    for (let i = 0; i < cli.length; i++) differ += drawn[i] !== cli[i];
    return differ;
  };
  const differ = await pixelsDiffering(join(dir, "cli.png"), one);
  h.check(differ === 0, `the outline is the CLI's mask for the same point ${one.sent.clicks} (${differ} pixels differ)`);

  // Alt-click: a point that is not the object; the photo is not encoded again.
  await page.evaluate(() => (window.instainpaint.lastSelect = null));
  await page.keyboard.down("Alt");
  await page.mouse.click(box.x + 0.1 * box.width, box.y + 0.1 * box.height);
  await page.keyboard.up("Alt");
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const two = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(!two.error && two.sent.notClicks !== "" && two.sent.clicks === one.sent.clicks && two.scores.length === 1,
    `alt-click sends a point that is not the object (${two.error ?? JSON.stringify(two.sent)})`);
  h.check(two.ms.encode === 0, `the second click runs the decoder alone (encode ${two.ms.encode} ms)`);

  // The box tool: a box dragged around the object is the segmenter's prompt, the CLI's --box mask.
  await page.evaluate(() => (window.instainpaint.lastSelect = null));
  await page.locator("#photo-box").click();
  await page.mouse.move(box.x + 0.35 * box.width, box.y + 0.4 * box.height);
  await page.mouse.down();
  await page.mouse.move(box.x + 0.6 * box.width, box.y + 0.7 * box.height, { steps: 4 });
  await page.mouse.move(box.x + 0.85 * box.width, box.y + 0.95 * box.height, { steps: 4 });
  await page.mouse.up();
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const boxed = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(!boxed.error && boxed.how === "segmenter" && boxed.sent.box !== "" && boxed.sent.clicks === "" &&
    boxed.scores.length === 1 && boxed.ms.encode === 0,
    `a box dragged on the photo prompts the segmenter, the decoder alone (${boxed.error ?? JSON.stringify(boxed.sent)})`);
  h.run(["segment", "--segmenter", fixture, "--image", photo, "--box", boxed.sent.box, "--precision", "fp32",
    "--out", join(dir, "cli-box.png"), "--json"]);
  const boxDiffer = await pixelsDiffering(join(dir, "cli-box.png"), boxed);
  h.check(boxDiffer === 0, `the box's outline is the CLI's mask for --box ${boxed.sent.box} (${boxDiffer} pixels differ)`);
  // Then a shift-click with the click tool adds a point to the box.
  await page.evaluate(() => (window.instainpaint.lastSelect = null));
  await page.locator("#pick").click();
  await page.keyboard.down("Shift");
  await page.mouse.click(box.x + 0.6 * box.width, box.y + 0.68 * box.height);
  await page.keyboard.up("Shift");
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const boxAndClick = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(!boxAndClick.error && boxAndClick.sent.box === boxed.sent.box && boxAndClick.sent.clicks !== "",
    `shift-click after the box sends both (${boxAndClick.error ?? JSON.stringify(boxAndClick.sent)})`);

  // The splats on screen: the camera on that view, a click; the selection is the outline's splats.
  await page.evaluate(() => (window.instainpaint.lastSelect = null));
  await page.evaluate((i) => window.instainpaint.jumpToView(i), index);
  await page.locator("#fill-click").click();
  const canvas = await page.locator("#fill-canvas").boundingBox();
  await page.mouse.click(canvas.x + 0.5 * canvas.width, canvas.y + 0.6 * canvas.height);
  await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 60000 });
  const splats = await page.evaluate(() => window.instainpaint.lastSelect);
  h.check(!splats.error && splats.how === "segmenter" && splats.selected > 0 && splats.selected < splats.total,
    `a click on the splats selects under the segmenter's outline (${splats.error ?? `${splats.selected} of ${splats.total}`})`);
  console.log(`measured: click on ${splats.total} splats to the drawn selection ${splats.clientSeconds.toFixed(2)} s ` +
    `(server: render and encode ${splats.ms.encode.toFixed(0)} ms, decode ${splats.ms.decode.toFixed(0)} ms, select ` +
    `${splats.ms.select.toFixed(0)} ms)`);
  h.check(errors.length === 0, `no console errors ${JSON.stringify(errors)}`);
} finally {
  await browser.close();
  server.stop();
}
