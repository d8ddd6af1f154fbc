// serve --inpainter with a LaMa file (the small fixture of tests/inpaint in place of big-lama's
// weights), in headless Chromium on the statue: the page names it as Run's reference when none is
// given and offers it first for Fill (selected); a Run without a reference is painted by it and
// the page says so.
import { join, resolve } from "node:path";
import * as h from "./harness.mjs";

h.skipUnlessReady();
const statue = h.sharedScene("statue");
const dir = h.scratch("inpainter");
const server = await h.serve(["--scene", statue, "--height", "128", "--views", "2", "--inpainter",
  resolve("tests/inpaint/fixture/lama-small/models/best.ckpt"), "--out", join(dir, "serve")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 1200, height: 800 } });
  const errors = h.collectErrors(page);
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  const network = "LaMa FFC-ResNet (ngf 8, 2 blocks)";
  const info = await page.evaluate(() => window.instainpaint.info.inpainter);
  h.check(info.name === "lama" && info.network === network && info.sha256.length === 64 && info.file === "best.ckpt",
    `the page knows the server's inpainter, its file by name only (${JSON.stringify(info)})`);
  await page.locator(`#strip figure[data-index="0"]`).click();
  const reference = await page.evaluate(() => document.getElementById("reference-default").textContent);
  h.check(reference === `(none: ${network})`, `Run's reference without one is LaMa's (${reference})`);
  const choice = await page.evaluate(() => {
    const select = document.getElementById("fill-inpainter");
    return { value: select.value, first: select.options[0].value, all: [...select.options].map((o) => o.value) };
  });
  h.check(choice.value === "lama" && choice.first === "lama" && choice.all.includes("ns"),
    `Fill offers LaMa first, selected (${JSON.stringify(choice)})`);
  // Run with the view's mask and no reference: LaMa paints it, and the page says so.
  const index = await page.evaluate(() => window.instainpaint.info.scene.views.findIndex((v) => v.name === "IMG_2707"));
  await page.locator(`#strip figure[data-index="${index}"]`).click();
  await page.locator("#mask-file").setInputFiles(join(statue, "images_2", "label", "IMG_2707.png"));
  await page.waitForFunction(() => {  // the file drawn onto the editor (decoded asynchronously)
    const c = document.getElementById("paint-canvas");
    const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
    for (let k = 3; k < d.length; k += 4) if (d[k] > 0) return true;
    return false;
  }, null, { timeout: 60000 });
  await page.locator("#run").click();
  await page.waitForFunction(() => window.instainpaint.lastRun, null, { timeout: 300000 });
  const run = await page.evaluate(() => window.instainpaint.lastRun);
  const said = await page.evaluate(() => document.getElementById("status").textContent);
  h.check(run.state === "done" && run.result.reference === "lama" && said.includes(`the reference painted by ${network}`),
    `Run without a reference is painted by LaMa and says so (${run.result?.reference}: ${said})`);
  h.check(errors.length === 0, `no console errors ${JSON.stringify(errors)}`);
} finally {
  await browser.close();
  server.stop();
}
