// The viewer in headless Chromium: it loads a splat PLY, the canvas is not blank, and a frame
// from a scene camera matches `instainpaint render` of the same PLY from that camera, also when
// the page is given the SPZ or compressed PLY written here (Spark decodes them).
import { existsSync, writeFileSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import * as h from "./harness.mjs";

h.skipUnlessReady();
const dir = h.scratch("view");
const { scene, ply } = h.roomWithGaussians(dir);
const server = await h.serve(["--scene", scene, "--ply", ply, "--out", join(dir, "serve")]);
const browser = await h.browser();
try {
  // Without the token in the address (and so without its cookie) nothing is served.
  const stranger = await browser.newPage();
  const denied = await stranger.goto(server.base);
  h.check(denied.status() === 403 && (await denied.text()).includes("missing token"),
    `without the token the page is refused (${denied.status()})`);
  await stranger.close();

  const page = await browser.newPage({ viewport: { width: 900, height: 600 } });
  const errors = h.collectErrors(page);

  // From scene view 1, at its size, with its intrinsics.
  await page.goto(server.page("view=1&exact=1"));
  await page.evaluate(() => window.instainpaint.ready);
  const shot = join(dir, "page-view_001.png");
  writeFileSync(shot, await h.settledScreenshot(page, page.locator("canvas").first()));
  h.run(["render", "--ply", ply, "--scene", scene, "--views", "view_001", "--no-video", "--out",
    join(dir, "render")]);
  const m = JSON.parse(h.run(["metrics", shot, join(dir, "render", "rgb", "0000.png"), "--json"]));
  const psnr = m.psnr === "inf" ? Infinity : m.psnr;
  console.log(`page vs render from view_001: PSNR ${psnr.toFixed(2)} dB, SSIM ${m.ssim.toFixed(3)}`);
  // Both draw the same Gaussians; they differ in sorting (Spark sorts per splat by distance,
  // ours per tile by depth), in 8-bit blending on the GPU and in cut-offs: 42 dB measured.
  h.check(psnr >= 35, `the page's frame matches instainpaint render (PSNR ${psnr.toFixed(2)} >= 35 dB)`);

  // The same splats as SPZ (the jobs' download) and as compressed PLY (what the page gets from
  // jobs), both written here: drawn like the float PLY's render.
  for (const file of ["room.spz", "room.compressed.ply"]) {
    const compressed = join(dir, file);
    h.run(["convert", ply, compressed]);
    const other = await h.serve(["--scene", scene, "--ply", compressed, "--out", join(dir, `serve-${file}`)]);
    const cpage = await browser.newPage({ viewport: { width: 900, height: 600 } });
    errors.push(...h.collectErrors(cpage));
    await cpage.goto(other.page("view=1&exact=1"));
    await cpage.evaluate(() => window.instainpaint.ready);
    const cshot = join(dir, `page-view_001-${file}.png`);
    writeFileSync(cshot, await h.settledScreenshot(cpage, cpage.locator("canvas").first()));
    const mc = JSON.parse(h.run(["metrics", cshot, join(dir, "render", "rgb", "0000.png"), "--json"]));
    const cpsnr = mc.psnr === "inf" ? Infinity : mc.psnr;
    console.log(`page (${file}) vs render of the float PLY from view_001: PSNR ${cpsnr.toFixed(2)} dB, SSIM ${mc.ssim.toFixed(3)}`);
    h.check(cpsnr >= 35, `${file} written here is drawn like the PLY's render (PSNR ${cpsnr.toFixed(2)} >= 35 dB)`);
    await cpage.close();
    other.stop();
  }

  const coverage = await page.evaluate(h.drawnFraction);
  h.check(coverage > 0.5, `the canvas is not blank (${(100 * coverage).toFixed(0)} % of pixels drawn)`);

  // A shared real capture in SuperSplat's compressed PLY, served without a scene: framed and drawn.
  const guitar = resolve("../shared/data/splats/guitar.compressed.ply");
  // As every test: a shared data folder counts only when whole (its PROVENANCE.md is there).
  if (existsSync(guitar) && existsSync(join(dirname(guitar), "PROVENANCE.md"))) {
    const other = await h.serve(["--ply", guitar, "--out", join(dir, "serve-guitar")]);
    const gpage = await browser.newPage({ viewport: { width: 640, height: 480 } });
    const gerrors = h.collectErrors(gpage);
    await gpage.goto(other.url);
    await gpage.evaluate(() => window.instainpaint.ready);
    await h.settled(gpage);
    writeFileSync(join(dir, "page-guitar.png"), await gpage.locator("#viewer canvas").screenshot());
    const drawn = await gpage.evaluate(h.drawnFraction);
    h.check(drawn > 0.05, `the shared compressed PLY is drawn (${(100 * drawn).toFixed(0)} % of pixels)`);
    errors.push(...gerrors);
    await gpage.close();
    other.stop();

    // Page load to first frame of the same capture as a float PLY and as SPZ (what serve sent before),
    // here and over a 50 Mbit/s link (Chromium's network emulation); measured only.
    const firstFrame = {};
    for (const kind of h.measure ? ["ply", "spz"] : []) {
      const file = join(dir, `guitar.${kind}`);
      h.run(["convert", guitar, file]);
      const s = await h.serve(["--ply", file, "--out", join(dir, `serve-guitar-${kind}`)]);
      for (const link of ["local", "50 Mbit/s"]) {
        const p = await browser.newPage({ viewport: { width: 640, height: 480 } });
        errors.push(...h.collectErrors(p));
        if (link !== "local") {
          const cdp = await p.context().newCDPSession(p);
          await cdp.send("Network.emulateNetworkConditions",
            { offline: false, latency: 20, downloadThroughput: 50e6 / 8, uploadThroughput: 50e6 / 8 });
        }
        await p.goto(s.url);
        await p.evaluate(() => window.instainpaint.ready);
        firstFrame[`${kind}, ${link}`] = await p.evaluate(() => window.instainpaint.firstFrameMs);
        await p.close();
      }
      s.stop();
    }
    if (h.measure) console.log(`measured: guitar (90,854 splats) page load to first frame (ms): ${JSON.stringify(firstFrame)}`);
  }

  // Opened on a scene alone: the server reconstructs it at start, the page shows it in 3D when
  // ready and opens the editor on the network's reference view, ready to paint.
  const bare = await h.serve(["--scene", scene, "--height", "64", "--out", join(dir, "serve-bare")]);
  const bpage = await browser.newPage({ viewport: { width: 900, height: 600 } });
  const berrors = h.collectErrors(bpage);
  await bpage.goto(bare.url);
  await bpage.evaluate(() => window.instainpaint.ready);
  await h.settled(bpage);
  writeFileSync(join(dir, "page-scene-alone.png"), await bpage.screenshot());
  const shown = await bpage.evaluate(() => ({ url: window.instainpaint.loadedUrl, hud: document.getElementById("hud").textContent,
    editing: !document.getElementById("edit-panel").hidden, view: document.getElementById("edit-view").textContent }));
  h.check(/^\/api\/jobs\/\d+\/gaussians\.compressed\.ply$/.test(shown.url ?? ""),
    `the scene's reconstruction is on screen, as compressed PLY (${shown.url})`);
  const bdrawn = await bpage.evaluate(h.drawnFraction);
  h.check(bdrawn > 0.3, `and drawn (${(100 * bdrawn).toFixed(0)} % of pixels)`);
  h.check(shown.editing && /^view_\d+$/.test(shown.view), `the editor is open on the reference view (${shown.view})`);
  errors.push(...berrors);
  await bpage.close();
  bare.stop();

  // The interactive viewer: first frame, frames per second (software GL: a floor), bundle size.
  const viewer = await browser.newPage({ viewport: { width: 900, height: 600 } });
  const viewerErrors = h.collectErrors(viewer);
  await viewer.goto(server.url);
  await viewer.evaluate(() => window.instainpaint.ready);
  await h.frames(viewer, h.measure ? 20 : 2);
  if (h.measure) {  // the software-GL frame rate: frames drawn back to back
    const since = await viewer.evaluate(() => [window.instainpaint.frames, performance.now()]);
    await h.frames(viewer, 20);
    const fps = await viewer.evaluate(([f, t]) => (1000 * (window.instainpaint.frames - f)) / (performance.now() - t), since);
    const stats = { firstFrameMs: await viewer.evaluate(() => window.instainpaint.firstFrameMs), fps };
    const bundle = (await (await server.get("app.js")).arrayBuffer()).byteLength;
    console.log(`measured: page load to first frame ${stats.firstFrameMs.toFixed(0)} ms, ${stats.fps.toFixed(1)} fps ` +
      `(900x600, headless Chromium, SwiftShader), bundle ${(bundle / 1e6).toFixed(2)} MB`);
  }
  h.check(errors.length === 0 && viewerErrors.length === 0, `no console errors ${JSON.stringify([...errors, ...viewerErrors])}`);
} finally {
  await browser.close();
  server.stop();
}
