// The page opened on a scene with splats shows them from the capture's first camera, upright,
// whichever way the capture's world is turned: the same room served as written (one up) and
// with its world turned half a turn about x (cameras and splats alike: the other up). A click
// on a view of the strip keeps the picture upright.
import { copyFileSync, cpSync, readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import * as h from "./harness.mjs";

// An LLFF poses_bounds.npy with the world turned half a turn about x: rows y and z of every
// camera-to-world matrix negated (each row: 3 x 5 pose, row-major, then near and far).
function turnPoses(file) {
  const bytes = readFileSync(file);
  const start = bytes.indexOf(0x0a) + 1;  // the header ends with a newline
  const values = new Float64Array(bytes.buffer.slice(bytes.byteOffset + start, bytes.byteOffset + bytes.length));
  for (let row = 0; row < values.length / 17; ++row)
    for (const i of [1, 2]) for (let j = 0; j < 4; ++j) values[row * 17 + i * 5 + j] *= -1;
  writeFileSync(file, Buffer.concat([bytes.subarray(0, start), Buffer.from(values.buffer)]));
}

// A binary 3DGS PLY with the same turn: positions (x, -y, -z), rotations q -> (1, 0, 0, 0)-turn * q.
function turnPly(from, to) {
  const bytes = readFileSync(from);
  const end = bytes.indexOf("end_header\n") + "end_header\n".length;
  const header = bytes.subarray(0, end).toString("latin1");
  const count = Number(header.match(/element vertex (\d+)/)[1]);
  const names = [...header.matchAll(/property float (\w+)/g)].map((m) => m[1]);
  const at = Object.fromEntries(names.map((n, i) => [n, i]));
  const rows = new Float32Array(bytes.buffer.slice(bytes.byteOffset + end, bytes.byteOffset + end + count * names.length * 4));
  for (let k = 0; k < count; ++k) {
    const r = rows.subarray(k * names.length, (k + 1) * names.length);
    r[at.y] = -r[at.y];
    r[at.z] = -r[at.z];
    const [w, x, y, z] = [r[at.rot_0], r[at.rot_1], r[at.rot_2], r[at.rot_3]];
    [r[at.rot_0], r[at.rot_1], r[at.rot_2], r[at.rot_3]] = [-x, w, -z, y];
  }
  writeFileSync(to, Buffer.concat([bytes.subarray(0, end), Buffer.from(rows.buffer)]));
}

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
// A view's camera centre and up (c2w row-major, OpenGL axes: +y is the picture's up).
const centreOf = (v) => [v.c2w[3], v.c2w[7], v.c2w[11]];
const upOf = (v) => [v.c2w[1], v.c2w[5], v.c2w[9]];

h.skipUnlessReady();
const dir = h.scratch("orientation");
const { scene, ply } = h.roomWithGaussians(dir);
const turned = join(dir, "turned");
cpSync(scene, turned, { recursive: true });
turnPoses(join(turned, "poses_bounds.npy"));
turnPly(ply, join(dir, "turned.ply"));
copyFileSync(ply, join(dir, "room.ply"));

const browser = await h.browser();
const ups = [];
try {
  for (const [name, sceneDir, file] of [["as written", scene, join(dir, "room.ply")], ["turned", turned, join(dir, "turned.ply")]]) {
    const server = await h.serve(["--scene", sceneDir, "--ply", file, "--out", join(dir, `serve-${ups.length}`)]);
    const page = await browser.newPage({ viewport: { width: 900, height: 600 } });
    const errors = h.collectErrors(page);
    await page.goto(server.url);
    await page.evaluate(() => window.instainpaint.ready);
    await h.settled(page);
    writeFileSync(join(dir, `page-${ups.length}.png`), await page.screenshot());
    const { views, pose, sceneUp } = await page.evaluate(() =>
      ({ views: window.instainpaint.info.scene.views, pose: window.instainpaint.pose(), sceneUp: window.instainpaint.sceneUp }));
    ups.push(sceneUp);
    const first = views[0];
    const away = Math.hypot(...pose.position.map((p, i) => p - centreOf(first)[i]));
    h.check(away < 1e-4, `${name}: opened at the capture's first camera (${away.toExponential(1)} from it)`);
    // Upright: the screen's up within 45 degrees of the camera's (the orbit levels the roll to the
    // scene's up); upside down is near -1.
    h.check(dot(pose.up, upOf(first)) > 0.7,
      `${name}: upright as that camera took it (screen up · its up = ${dot(pose.up, upOf(first)).toFixed(3)})`);
    const drawn = await page.evaluate(h.drawnFraction);
    h.check(drawn > 0.3, `${name}: the splats are in sight (${(100 * drawn).toFixed(0)} % of pixels drawn)`);
    // A click on another view of the strip.
    await page.locator("#strip figure").nth(3).click();
    await h.frames(page, 4);
    const after = await page.evaluate(() => window.instainpaint.pose());
    h.check(dot(after.up, upOf(views[3])) > 0.7,
      `${name}: a click on view 3 shows it upright (${dot(after.up, upOf(views[3])).toFixed(3)})`);
    h.check(errors.length === 0, `${name}: no console errors (${errors.join("; ")})`);
    await page.close();
    server.stop();
  }
  // The test covered both: one capture's up is +y, the other's -y.
  h.check(ups[0][1] * ups[1][1] < 0 && Math.abs(ups[0][1]) > 0.9,
    `one capture is y-up, the other y-down (${JSON.stringify(ups.map((u) => u.map((c) => +c.toFixed(2))))})`);
} finally {
  await browser.close();
}
