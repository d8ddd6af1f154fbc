// The page as a new user sees it on a capture with splats: `serve --ply SPLATS --scene CAPTURE`,
// opened (screenshot 1), a view of the strip clicked (screenshot 2), one stroke painted over a world
// point on that view and *Fill* run (screenshot 3, the filled splats from the same camera).
//
//   node scripts/serve-fill-screenshot.mjs BIN SPLATS CAPTURE IMAGES VIEW X,Y,Z RADIUS_PX OUT_DIR
import { mkdirSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import * as h from "../tests/web/browser/harness.mjs";

const [, , , splats, capture, images, view, point, radius, out] = process.argv;
mkdirSync(out, { recursive: true });
h.skipUnlessReady();
const server = await h.serve(["--ply", splats, "--scene", capture, "--images", images, "--out", join(out, "serve")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 1100, height: 650 } });
  const errors = h.collectErrors(page);
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  await h.frames(page, 6);
  writeFileSync(join(out, "1-opened.png"), await page.screenshot());
  const index = await page.evaluate((name) => window.instainpaint.info.scene.views.findIndex((v) => v.name === name), view);
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
  await page.locator("#fill-run").click();
  await page.waitForFunction(() => window.instainpaint.lastFill || window.instainpaint.lastRun?.state === "refused",
    null, { timeout: 600000 });
  await h.frames(page, 6);
  writeFileSync(join(out, "3-filled.png"), await page.screenshot());
  const fill = await page.evaluate(() => window.instainpaint.lastFill);
  console.log(JSON.stringify({ fill: fill?.result?.fill, seconds: fill?.seconds, errors }));
} finally {
  await browser.close();
  server.stop();
}
