// Times the page's click on splats (Remove and fill, click): serve a capture with a splat file,
// look through one of its views, click at a point of it three times (the first reads the file),
// and print the time from the click to the drawn selection and the server's part of it.
//   node scripts/measure-page-click.mjs BUILD/instainpaint SCENE IMAGES SPLATS VIEW X,Y
// (X,Y in pixels of the view's photo; the page's view has the view's vertical field of view.)
import { join } from "node:path";
import * as h from "../tests/web/browser/harness.mjs";

const [, , , scene, images, splats, viewName, at] = process.argv;
h.skipUnlessReady();
const dir = h.scratch("click");
const server = await h.serve(["--scene", scene, "--images", images, "--ply", splats, "--out", join(dir, "serve")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 1000, height: 600 } });
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  const index = await page.evaluate((n) => window.instainpaint.info.scene.views.findIndex((v) => v.name === n), viewName);
  await page.evaluate((i) => window.instainpaint.jumpToView(i), index);
  await page.locator("#fill-click").click();
  await page.waitForTimeout(2000);  // a user's move to the object: the server reads the splats meanwhile
  const [px, py] = at.split(",").map(Number);
  const point = await page.evaluate(([i, x, y]) => {
    const view = window.instainpaint.info.scene.views[i];
    const r = document.getElementById("fill-canvas").getBoundingClientRect();
    const s = r.height / view.height;
    return [r.x + r.width / 2 + (x - view.width / 2) * s, r.y + y * s];
  }, [index, px, py]);
  for (let k = 0; k < 3; k++) {
    await page.evaluate(() => (window.instainpaint.lastSelect = null));
    await page.mouse.click(...point);
    await page.waitForFunction(() => window.instainpaint.lastSelect, null, { timeout: 120000 });
    const s = await page.evaluate(() => window.instainpaint.lastSelect);
    if (s.error) throw new Error(s.error);
    console.log(`click ${k + 1}: ${s.clientSeconds.toFixed(2)} s to the drawn selection, ${s.selected} of ${s.total} ` +
      `splats (server: read ${s.ms.read.toFixed(0)} ms, select ${s.ms.select.toFixed(0)} ms, draw ${s.ms.draw.toFixed(0)} ms)`);
  }
} finally {
  await browser.close();
  server.stop();
}
