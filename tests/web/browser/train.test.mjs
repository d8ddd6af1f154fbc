// A capture walked around its object, opened on its own (serve --scene): the page offers to train
// splats of the whole capture (3DGS, the server's `reconstruct`), shows the training's progress,
// puts the trained splats on screen with the remove-and-fill panel, and a Fill on them removes the
// object's splats and fills the hole.
import { readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import * as h from "./harness.mjs";

h.skipUnlessReady();
const dir = h.scratch("train");
h.run(["synth", "--out", join(dir, "rooms"), "--scenes", "1", "--seed", "7", "--rings", "1", "--views", "24",
  "--test-views", "1", "--width", "128", "--height", "96", "--object", "procedural", "--degrade", "none", "--no-depth"]);
const room = join(dir, "rooms", "scene_000");
const bounds = JSON.parse(readFileSync(join(room, "synth.json"), "utf8")).object_bounds;
const server = await h.serve(["--scene", room, "--height", "64", "--views", "3", "--out", join(dir, "serve")]);
const browser = await h.browser();
try {
  const page = await browser.newPage({ viewport: { width: 900, height: 600 } });
  const errors = h.collectErrors(page);
  await page.goto(server.url);
  await page.evaluate(() => window.instainpaint.ready);
  h.check(await page.locator("#train-panel").isVisible(), "a capture opened on its own offers to train its splats");

  // 150 steps, as a user would choose a length (the menu's shortest is a minute).
  const stages = [];
  await page.evaluate(() => {
    const length = document.getElementById("train-length");
    length.add(new Option("150 steps", "150"));
    length.value = "150";
  });
  await page.locator("#train").click();
  while (!(await page.evaluate(() => window.instainpaint.lastTrain || document.getElementById("status").classList.contains("error")))) {
    stages.push(await page.locator("#status").textContent());
    await page.waitForTimeout(200);
  }
  const job = await page.evaluate(() => window.instainpaint.lastTrain);
  h.check(job?.state === "done" && job.result.trained.training.steps === 150,
    `the training ran its 150 steps (${JSON.stringify(job?.result?.trained?.training?.steps ?? await page.locator("#status").textContent())})`);
  h.check(stages.some((s) => /training the whole capture: step \d+, \d+ splats/.test(s)),
    `its progress was shown (${[...new Set(stages)].slice(-3).join(" | ")})`);
  h.check(await page.evaluate(() => window.instainpaint.loadedUrl) === job.result.splats, "the trained splats are on screen");
  h.check(await page.locator("#fill-panel").isVisible(), "with the remove-and-fill panel");
  writeFileSync(join(dir, "trained.png"), await page.screenshot());
  console.log(`picture: ${join(dir, "trained.png")}; trained ${job.result.trained.splats} splats in ${job.seconds.toFixed(1)} s ` +
    `(PSNR ${job.result.trained.psnr.toFixed(2)} dB over the training views)`);

  const size = 2.2 * bounds.radius;
  await page.evaluate(([c, s]) => window.instainpaint.setFillBox(c, [s, s, s]), [bounds.centre, size]);
  await page.locator("#fill-run").click();
  await page.waitForFunction(() => window.instainpaint.lastFill || document.getElementById("status").classList.contains("error"),
    null, { timeout: 300000 });
  const fill = await page.evaluate(() => window.instainpaint.lastFill);
  h.check(fill?.state === "done" && fill.result.fill.removed > 0 && fill.result.fill.added > 0,
    `Fill on the trained splats removes the object's and fills the hole (${JSON.stringify(fill?.result?.fill ?? await page.locator("#status").textContent())})`);

  // A length the page does not offer is refused with the reason.
  const answer = await fetch(new URL("/api/train", server.base), { method: "POST",
    headers: { "X-Instainpaint-Token": server.token }, body: new URLSearchParams({ length: "30m" }) });
  const refused = [answer.status, (await answer.json()).error];
  h.check(refused[0] === 400 && refused[1] === "length '30m': the page trains for at most 20 minutes or 30,000 steps",
    `a training of 30 minutes is refused (${refused})`);
  h.check(errors.length === 0, `no console errors ${JSON.stringify(errors)}`);
} finally {
  await browser.close();
  server.stop();
}
