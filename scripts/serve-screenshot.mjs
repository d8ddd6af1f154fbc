// The README's picture of `instainpaint serve` (docs/serve.png), made the way a user works:
// the demo room (run `make demo` first), its reference view's mask loaded into the painter,
// Preview masks, Run; then a screenshot of the page. Prints the edit loop's time.
//   node scripts/serve-screenshot.mjs [build/instainpaint] [docs/serve.png]
import { writeFileSync, readFileSync } from "node:fs";
import { join } from "node:path";
import * as h from "../tests/web/browser/harness.mjs";

h.skipUnlessReady();
const out = process.argv[3] ?? "docs/serve.png";
const scene = "demo-out/data/scene_000";
const reference = JSON.parse(readFileSync(join(scene, "synth.json"), "utf8")).context[0];
const server = await h.serve(["--scene", scene, "--ply", "demo-out/with-object/gaussians.ply", "--height", "128",
  "--out", h.scratch("screenshot")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 940 } });
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  const index = await page.evaluate((name) => window.instainpaint.info.scene.views.findIndex((v) => v.name === name), reference);
  await page.locator(`#strip figure[data-index="${index}"]`).click();
  await page.locator("#mask-file").setInputFiles(join(scene, "images_4", "label", `${reference}.png`));
  await page.locator("#reference-file").setInputFiles(join(scene, "reference.png"));
  await page.locator("#refine").fill("100");
  await page.locator("#run").click();
  await page.waitForFunction(() => window.instainpaint.lastRun, null, { timeout: 600000 });
  const run = await page.evaluate(() => window.instainpaint.lastRun);
  console.log(`Run to new splats on screen: ${run.clientSeconds.toFixed(2)} s (server ${run.seconds.toFixed(2)} s, ` +
    `${run.result.gaussians} Gaussians, refine ${run.result.refine?.steps ?? 0})`);
  console.log(`  of which (ms): ${JSON.stringify(run.parts)}`);
  await page.locator("#viewer canvas").hover();
  for (let k = 0; k < 4; k++) await page.keyboard.press("s");  // fly back a little
  await h.frames(page, 4);
  // Frames drawn back to back at this size (software WebGL in headless Chromium: a floor).
  const since = await page.evaluate(() => [window.instainpaint.frames, performance.now()]);
  await h.frames(page, 6);
  const fps = await page.evaluate(([f, t]) => (1000 * (window.instainpaint.frames - f)) / (performance.now() - t), since);
  console.log(`viewer: ${fps.toFixed(2)} fps at ${await page.evaluate(() => {
    const c = document.querySelector("#viewer canvas");
    return `${c.width}x${c.height}`;
  })} with ${run.result.gaussians} Gaussians`);
  writeFileSync(out, await page.screenshot());
  console.log(`wrote ${out}`);
} finally {
  await browser.close();
  server.stop();
}
