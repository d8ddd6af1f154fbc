// The page of `instainpaint serve`: a Gaussian-splat viewer (three.js + Spark) with the scene's
// cameras, a one-mask editor that runs the server's edit jobs, and "remove and fill" for the
// splats on screen (a box with handles, or a stroke on the view on screen).
//
// URL parameters: ?ply=<i> shows the i-th PLY given to serve first (or ?ply=/api/jobs/<id>/
// gaussians.ply, an edit's result); ?view=<i>&exact=1 renders from scene view i with its exact
// intrinsics at its size on white (no controls), for comparisons with `instainpaint render`.
// window.instainpaint exposes the state that tests and measurements read.
import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import { TransformControls } from "three/examples/jsm/controls/TransformControls.js";
import { SparkRenderer, SplatEdit, SplatEditRgbaBlendMode, SplatEditSdf, SplatEditSdfType, SplatMesh } from "@sparkjsdev/spark";

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const exact = params.get("exact") === "1";

const api = {
  info: null,
  loadedUrl: null, // the PLY on screen
  frames: 0,
  fps: 0,
  firstFrameMs: null, // navigation start (the bundle's download included) to the first frame with splats
  ready: null, // resolves when the first PLY is on screen
  job: null, // the running job's last polled state
  lastRun: null, // the last Run or Preview: {id, state, error, result, seconds (click to splats on screen)}
  lastFill: null, // the last Fill: the job, and seconds from the click to the filled splats on screen
  lastSelect: null, // the last click's selection: the server's answer, and seconds from the click to it drawn
  fillBox: null, // the box's centre, size and turn (degrees about x, then y, then z), or null
  showPly,
  jumpToView,
  invalidate,
  // True when the picture on screen is final: no frames queued, no sort running or due, and the
  // last sort's order drawn (what tests wait for before a screenshot). Spark 2.2's renderer state
  // (public fields in its types; the version is pinned in web/package-lock.json).
  settled: () => framesToDraw <= 0 && !spark.sorting && !spark.sortDirty && spark.sortTimeoutId === -1 && !spark.dirty,
  setFillBox,
  screenPoint,
  sceneUp: null, // the scene's up (its cameras' mean), when it has cameras
  // Where the viewer's camera is and which world direction is up on the screen.
  pose: () => ({
    position: camera.position.toArray(),
    up: new THREE.Vector3(0, 1, 0).applyQuaternion(camera.quaternion).toArray(),
  }),
};
window.instainpaint = api;

// ---- viewer ----------------------------------------------------------------------------
const viewer = $("viewer");
const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(exact ? 1 : window.devicePixelRatio);
viewer.prepend(renderer.domElement);  // the first canvas: the painting one goes over it
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xffffff);
// As instainpaint's rasterizer (gsplat's classic mode) draws: 0.3 px² added to every
// projected covariance without opacity compensation, sorted by z-depth.
// Spark sorts in a worker; when a sort lands it asks for one more frame (onDirty), so the
// picture on screen ends sorted without a stream of frames.
const spark = new SparkRenderer({ renderer, preBlurAmount: 0.3, blurAmount: 0, sortRadial: false, maxStdDev: 3,
  onDirty: () => invalidate(1) });
scene.add(spark);
const camera = new THREE.PerspectiveCamera(50, 1, 0.01, 1000);
camera.position.set(0, 0, 3);
// Orbit controls keep the camera's up as the world's: made again when a scene says its up.
let controls = null;
function makeControls() {
  if (exact) return;
  controls?.dispose();
  controls = new OrbitControls(camera, renderer.domElement);
  controls.addEventListener("change", () => invalidate());
}
makeControls();
const frustums = new THREE.Group();
if (!exact) scene.add(frustums);
let mesh = null;
let exactView = null;

function resize() {
  if (exactView) {
    renderer.setSize(exactView.width, exactView.height, false);
    renderer.domElement.style.width = `${exactView.width}px`;
    renderer.domElement.style.height = `${exactView.height}px`;
    return;
  }
  const w = viewer.clientWidth, h = viewer.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener("resize", () => {
  resize();
  invalidate();
});

// A scene camera (c2w row-major, OpenGL axes, as the server sends it) as the viewer's pose.
function poseOf(view) {
  const m = new THREE.Matrix4().fromArray(view.c2w).transpose();
  const position = new THREE.Vector3(), quaternion = new THREE.Quaternion();
  m.decompose(position, quaternion, new THREE.Vector3());
  return { position, quaternion };
}

// The pinhole projection of a view's intrinsics (principal point anywhere), OpenGL clip space.
function projectionOf(view, near = 0.01, far = 1000) {
  const { width: w, height: h, fx, fy, cx, cy } = view;
  return new THREE.Matrix4().set(
    (2 * fx) / w, 0, 1 - (2 * cx) / w, 0,
    0, (2 * fy) / h, (2 * cy) / h - 1, 0,
    0, 0, -(far + near) / (far - near), (-2 * far * near) / (far - near),
    0, 0, -1, 0);
}

function jumpToView(index) {
  const view = api.info.scene.views[index];
  const { position, quaternion } = poseOf(view);
  camera.position.copy(position);
  camera.quaternion.copy(quaternion);
  if (exactView) {
    camera.projectionMatrix.copy(projectionOf(view));
    camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
  } else {
    camera.fov = THREE.MathUtils.radToDeg(2 * Math.atan(view.height / (2 * view.fy)));
    camera.updateProjectionMatrix();
    // Orbit about a point in front of the camera, as far as the scene's centre.
    const forward = new THREE.Vector3(0, 0, -1).applyQuaternion(quaternion);
    const distance = Math.max(0.2, position.length());
    controls.target.copy(position).addScaledVector(forward, distance);
    controls.update();
  }
  camera.updateMatrixWorld(true);
  frustums.children.forEach((f, i) => (f.visible = i !== index));  // not the one we look through
  invalidate();
}

// The scene's up: its cameras' mean up (captures are y-up or y-down, and some tilted), so that
// the orbit turns about it and the views are shown upright.
function sceneUp(views) {
  const up = new THREE.Vector3();
  views.forEach((view) => up.add(new THREE.Vector3(0, 1, 0).applyQuaternion(poseOf(view).quaternion)));
  return up.lengthSq() > 1e-12 ? up.normalize() : new THREE.Vector3(0, 1, 0);
}

function addFrustums(views) {
  const size = 0.08;
  views.forEach((view) => {
    const { position, quaternion } = poseOf(view);
    const x = (size * view.width) / (2 * view.fx), y = (size * view.height) / (2 * view.fy);
    const corners = [[-x, -y], [x, -y], [x, y], [-x, y]].map(([a, b]) => new THREE.Vector3(a, b, -size));
    const points = [];
    corners.forEach((c, i) => points.push(new THREE.Vector3(), c, c, corners[(i + 1) % 4]));
    const geometry = new THREE.BufferGeometry().setFromPoints(points);
    const lines = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0x888888 }));
    lines.position.copy(position);
    lines.quaternion.copy(quaternion);
    frustums.add(lines);
  });
}

function frameSplats(box) {
  const centre = box.getCenter(new THREE.Vector3());
  const radius = Math.max(1e-3, box.getSize(new THREE.Vector3()).length() / 2);
  camera.up.set(0, -1, 0);
  makeControls();
  camera.position.copy(centre).add(new THREE.Vector3(0, -0.3 * radius, -2.2 * radius));
  camera.lookAt(centre);
  controls?.target.copy(centre);
  controls?.update();
}

// Fly with the keyboard (W/S forward and back, A/D sideways, Q/E down and up), orbit with
// the mouse; the step scales with the distance to the orbit's centre.
window.addEventListener("keydown", (e) => {
  if (!controls || e.target instanceof HTMLInputElement) return;
  const moves = { w: [0, 0, -1], s: [0, 0, 1], a: [-1, 0, 0], d: [1, 0, 0], q: [0, -1, 0], e: [0, 1, 0] };
  const m = moves[e.key.toLowerCase()];
  if (!m) return;
  const step = 0.05 * camera.position.distanceTo(controls.target);
  const offset = new THREE.Vector3(...m).multiplyScalar(step).applyQuaternion(camera.quaternion);
  camera.position.add(offset);
  controls.target.add(offset);
  invalidate();
});

// The splat format by name (files given to serve have no extension in their URL: their name says).
function splatType(url) {
  const served = url.match(/^\/api\/plys\/(\d+)$/);
  const name = served ? api.info?.plys?.[Number(served[1])]?.name ?? "" : url;
  return /\.spz$/i.test(name) ? "spz" : "ply";
}

async function showPly(url) {
  const next = new SplatMesh({ url, fileType: splatType(url) });
  await next.initialized;
  if (mesh) {
    scene.remove(mesh);
    mesh.dispose?.();
  }
  mesh = next;
  scene.add(mesh);
  // Without scene cameras, frame the splats as 3DGS captures are usually oriented (y down).
  if (!api.info?.scene && api.loadedUrl === null) frameSplats(mesh.getBoundingBox(true));
  api.loadedUrl = url;
  invalidate(4);
  await new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve)));
  if (api.firstFrameMs === null) api.firstFrameMs = performance.now();  // since the navigation's start
  $("hud").dataset.ply = url;
}

// Frames are drawn on demand (a camera move, new splats, a resize), a few in a row so that
// Spark's sort, which runs in a worker, catches up: an idle page leaves the CPU to the
// server's jobs, and with software WebGL (seconds per frame) the page stays responsive.
let framesToDraw = 3;
function invalidate(frames = 3) {
  framesToDraw = Math.max(framesToDraw, frames);
}

let fpsFrames = 0, fpsSince = performance.now();
renderer.setAnimationLoop(() => {
  controls?.update();
  if (framesToDraw <= 0) {
    fpsFrames = 0;
    fpsSince = performance.now();
    return;
  }
  framesToDraw--;
  renderer.render(scene, camera);
  api.frames++;
  fpsFrames++;
  const now = performance.now();
  if (now - fpsSince >= 1000) {
    api.fps = (1000 * fpsFrames) / (now - fpsSince);
    fpsFrames = 0;
    fpsSince = now;
    if (!exact) $("hud").textContent = `${api.fps.toFixed(1)} fps · ${api.loadedUrl ?? "no splats"}`;
  }
});

// ---- splat list, before / after ----------------------------------------------------------
let beforeUrl = null, afterUrl = null;

function setActive(which) {
  $("before").classList.toggle("on", which === "before");
  $("after").classList.toggle("on", which === "after");
  showingBefore = which === "before";
  updateRegionPreview();
}
let showingBefore = true;

function listPlys(plys) {
  const box = $("plys");
  box.textContent = plys.length ? "" : "none given (serve --ply FILE)";
  plys.forEach(addPly);
}

// One more splat file to show (its button shows it as the scene "with object").
function addPly(p) {
  const box = $("plys");
  if (!box.querySelector("button")) box.textContent = "";
  const b = document.createElement("button");
  b.textContent = p.name;
  b.onclick = async () => {
    beforeUrl = p.url;
    await showPly(p.url);
    setActive("before");
  };
  box.appendChild(b);
}

// Downloads of the splats on screen: a job's in both formats, a served file as it is.
function setDownloads() {
  const url = api.loadedUrl;
  const links = [];
  const job = url?.match(/^(\/api\/jobs\/\d+\/gaussians)(\.compressed)?\.(ply|spz)$/);
  if (job) {
    links.push(`download: <a href="${job[1]}.ply?download=1">PLY</a>`);
    links.push(`<a href="${job[1]}.spz?download=1">SPZ (about a tenth of the size)</a>`);
    links.push(`<a href="${job[1]}.sog?download=1">SOG</a>`);
  } else if (url) {
    links.push(`<a href="${url}?download=1">download the splats on screen</a>`);
  }
  $("downloads").innerHTML = links.join(" · ");
}

$("before").onclick = async () => {
  if (beforeUrl) await showPly(beforeUrl);
  setActive("before");
  setDownloads();
};
$("after").onclick = async () => {
  if (afterUrl) await showPly(afterUrl);
  setActive("after");
  setDownloads();
};

// ---- views and the editor ------------------------------------------------------------------
let selected = -1;
const paintCanvas = $("paint-canvas");
let erasing = false;

function listViews(views) {
  const strip = $("strip");
  strip.textContent = views.length ? "" : "no scene (serve --scene DIR)";
  views.forEach((view, i) => {
    const figure = document.createElement("figure");
    figure.dataset.index = i;
    figure.title = `${view.name}: jump to this view and edit on it`;
    const img = document.createElement("img");
    img.src = view.image;
    img.loading = "lazy";
    img.alt = view.name;
    const overlay = document.createElement("canvas");
    overlay.className = "overlay";
    overlay.width = view.width;
    overlay.height = view.height;
    img.onload = () => (overlay.style.width = `${img.clientWidth}px`);
    const caption = document.createElement("figcaption");
    caption.textContent = view.name;
    figure.append(img, overlay, caption);
    figure.onclick = () => selectView(i);
    strip.appendChild(figure);
  });
}

function selectView(i) {
  selected = i;
  const view = api.info.scene.views[i];
  document.querySelectorAll("#strip figure").forEach((f) => f.classList.toggle("selected", Number(f.dataset.index) === i));
  jumpToView(i);
  if (!api.info.editing) return;
  $("edit-panel").hidden = false;
  $("edit-view").textContent = view.name;
  $("paint-image").src = view.image;
  paintCanvas.width = view.width;
  paintCanvas.height = view.height;
  viewClicks = [];
  viewNotClicks = [];
  viewBox = null;
}

// Where a pointer event falls on `canvas`, in the canvas's own pixels.
function canvasPixel(canvas, event) {
  const r = canvas.getBoundingClientRect();
  return [((event.clientX - r.left) * canvas.width) / r.width, ((event.clientY - r.top) * canvas.height) / r.height];
}

// A brush on `canvas`: red strokes of radius radiusOf() canvas pixels, or erasing while
// erasingNow(); returns the canvas's context.
function attachBrush(canvas, erasingNow, radiusOf, enabled = () => true) {
  const ctx = canvas.getContext("2d");
  let last = null;
  const stroke = (event) => {
    const [x, y] = canvasPixel(canvas, event);
    const radius = radiusOf();
    ctx.globalCompositeOperation = erasingNow() ? "destination-out" : "source-over";
    ctx.strokeStyle = ctx.fillStyle = "#ff0000";
    ctx.lineWidth = 2 * radius;
    ctx.lineCap = "round";
    ctx.beginPath();
    if (last) {
      ctx.moveTo(last[0], last[1]);
      ctx.lineTo(x, y);
      ctx.stroke();
    } else {
      ctx.arc(x, y, radius, 0, 2 * Math.PI);
      ctx.fill();
    }
    last = [x, y];
  };
  canvas.addEventListener("pointerdown", (e) => {
    if (!enabled()) return;
    canvas.setPointerCapture(e.pointerId);
    last = null;
    stroke(e);
  });
  canvas.addEventListener("pointermove", (e) => {
    if (enabled() && e.buttons & 1) stroke(e);
  });
  canvas.addEventListener("pointerup", () => (last = null));
  return ctx;
}
let picking = false; // the click tool: a click selects the object under it instead of painting
let boxing = false; // the box tool: a box dragged around the object
let viewClicks = []; // its clicks so far on the selected view, in the view's pixels
let viewNotClicks = []; // with a segmenter or a box: alt-clicks, points that are not the object
let viewBox = null; // the box dragged around the object, [x0, y0, x1, y1]
const paint = attachBrush(paintCanvas, () => erasing, () => (Number($("size").value) * paintCanvas.width) / 400,
  () => !picking && !boxing);
function setTool(tool) {
  erasing = tool === "eraser";
  picking = tool === "pick";
  boxing = tool === "photo-box";
  for (const t of ["brush", "eraser", "pick", "photo-box"]) $(t).classList.toggle("on", t === tool);
}
$("brush").onclick = () => setTool("brush");
$("eraser").onclick = () => setTool("eraser");
$("pick").onclick = () => setTool("pick");
$("photo-box").onclick = () => setTool("photo-box");
// The clicks after a click at (x, y): a plain click starts again, shift-click adds a point on the
// object, alt-click (with a segmenter, or after a box) a point that is not the object.
function nextClicks(e, x, y, clicks, notClicks) {
  if (e.altKey && ((api.info?.segmenter && clicks.length) || viewBox)) return [clicks, [...notClicks, [x, y]]];
  if (e.shiftKey) return [[...clicks, [x, y]], notClicks];
  return [[[x, y]], []];
}

// A click with the click tool. With a segmenter (serve --segmenter), the server outlines the
// object under the clicks on this view's photo; without, it selects the object in the scene's
// reconstruction and carves its outline by the photo. The outline becomes the painted region (Run
// and Preview use it).
paintCanvas.addEventListener("pointerdown", async (e) => {
  if (!picking || selected < 0) return;
  const [x, y] = canvasPixel(paintCanvas, e);
  const [clicks, notClicks] = nextClicks(e, x, y, viewClicks, viewNotClicks);
  const box = e.shiftKey || e.altKey ? viewBox : null;  // a plain click starts again
  const selection = await requestSelection({ view: String(selected), ...(box ? { box: boxText(box) } : {}) }, clicks,
    paint, notClicks);
  if (!selection) return;
  viewClicks = clicks;
  viewNotClicks = notClicks;
  viewBox = box;
  status(selection.how === "colour growth"
    ? `selected ${selection.selected} of the reconstruction's ${selection.total} points (${selection.pixels} pixels ` +
      `of the view); ${selection.clientSeconds.toFixed(2)} s: Run or Preview masks uses it, shift-click adds`
    : `${boxSelector(selection)}: ${selection.pixels} pixels of the view from ${box ? "a box and " : ""}` +
      `${clicks.length} point${clicks.length === 1 ? "" : "s"} on the object and ${notClicks.length} off it; ` +
      `${selection.clientSeconds.toFixed(2)} s: Run or Preview masks uses it, shift-click adds a point, alt-click ` +
      "marks what is not the object");
});

// The box tool: a box dragged on the photo (drawn as it is dragged), sent to the server when the
// button is released: the segmenter outlines the object in it, or without one GrabCut does by
// colour; a later shift-click adds points to it, alt-click points that are not the object.
const boxText = (b) => b.map((v) => +v.toFixed(2)).join(",");
const boxSelector = (selection) => (selection.how === "segmenter" ? api.info.segmenter.network : "GrabCut in the box");
let boxStart = null;
function draggedBox(e) {
  const [x, y] = canvasPixel(paintCanvas, e);
  return [Math.min(boxStart[0], x), Math.min(boxStart[1], y), Math.max(boxStart[0], x), Math.max(boxStart[1], y)];
}
paintCanvas.addEventListener("pointerdown", (e) => {
  if (!boxing || selected < 0) return;
  paintCanvas.setPointerCapture(e.pointerId);
  boxStart = canvasPixel(paintCanvas, e);
});
paintCanvas.addEventListener("pointermove", (e) => {
  if (!boxing || !boxStart) return;
  const [x0, y0, x1, y1] = draggedBox(e);
  paint.clearRect(0, 0, paintCanvas.width, paintCanvas.height);
  paint.strokeStyle = "#ff0000";
  paint.lineWidth = Math.max(2, paintCanvas.width / 300);
  paint.strokeRect(x0, y0, x1 - x0, y1 - y0);
});
paintCanvas.addEventListener("pointerup", async (e) => {
  if (!boxing || !boxStart) return;
  const box = draggedBox(e);
  boxStart = null;
  if (box[2] - box[0] < 2 || box[3] - box[1] < 2) return status("drag a box around the object", true);
  const selection = await requestSelection({ view: String(selected), box: boxText(box) }, [], paint);
  if (!selection) return;
  [viewClicks, viewNotClicks, viewBox] = [[], [], box];
  status(`${boxSelector(selection)}: ${selection.pixels} pixels of the view from the box; ` +
    `${selection.clientSeconds.toFixed(2)} s: Run or Preview masks uses it; with the click tool, shift-click adds a ` +
    "point, alt-click marks what is not the object");
});
$("clear").onclick = () => {
  paint.clearRect(0, 0, paintCanvas.width, paintCanvas.height);
  [viewClicks, viewNotClicks, viewBox] = [[], [], null];
};
$("mask-file").onchange = async (e) => {
  const file = e.target.files[0];
  if (!file) return;
  drawMaskInRed(paint, await createImageBitmap(file), 255);
};

// A black and white mask image drawn over a canvas as red (white = region), with `alpha`.
function drawMaskInRed(ctx, bitmap, alpha) {
  const { width, height } = ctx.canvas;
  ctx.clearRect(0, 0, width, height);
  ctx.drawImage(bitmap, 0, 0, width, height);
  const pixels = ctx.getImageData(0, 0, width, height);
  const d = pixels.data;  // byte by byte: an array a pixel made this seconds for a scene's views
  // White is the region; a mask of 0 and 1 (SPIn-NeRF's labels) too, as the commands read it.
  let brightest = 0;
  for (let k = 0; k < d.length; k += 4) brightest = Math.max(brightest, d[k]);
  const threshold = brightest > 1 ? 127 : 0;
  for (let k = 0; k < d.length; k += 4) {
    const on = d[k] > threshold;
    d[k] = on ? 255 : 0;
    d[k + 1] = d[k + 2] = 0;
    d[k + 3] = on ? alpha : 0;
  }
  ctx.putImageData(pixels, 0, 0);
}

// The region painted on `canvas` as a black and white PNG at its size.
async function maskBlob(canvas = paintCanvas) {
  const { width, height } = canvas;
  const painted = canvas.getContext("2d").getImageData(0, 0, width, height);
  const out = new OffscreenCanvas(width, height);
  const ctx = out.getContext("2d");
  const pixels = ctx.createImageData(width, height);
  const d = pixels.data;
  for (let k = 0; k < d.length; k += 4) {
    d[k] = d[k + 1] = d[k + 2] = painted.data[k + 3] > 0 ? 255 : 0;
    d[k + 3] = 255;
  }
  ctx.putImageData(pixels, 0, 0);
  return out.convertToBlob({ type: "image/png" });
}

function status(text, error = false) {
  $("status").textContent = text;
  $("status").classList.toggle("error", error);
}

async function drawMaskOverlays(masks) {
  const figures = document.querySelectorAll("#strip figure");
  await Promise.all(
    api.info.scene.views.map(async (view, i) => {
      // Read back pixel by pixel: a canvas kept in memory (one on the GPU reads back slowly).
      const ctx = figures[i].querySelector("canvas").getContext("2d", { willReadFrequently: true });
      ctx.clearRect(0, 0, ctx.canvas.width, ctx.canvas.height);
      if (masks[view.name]) drawMaskInRed(ctx, await createImageBitmap(await (await fetch(masks[view.name])).blob()), 140);
    }),
  );
}

// Starts a job (POST `path` with `body`) and polls it to its end; the job's state, or null
// when the server refused it (the reason is shown).
async function startAndWait(path, body) {
  const answer = await fetch(path, { method: "POST", body });
  const started = await answer.json();
  if (answer.status !== 202) {
    api.lastRun = { state: "refused", error: started.error };
    status(started.error ?? `error ${answer.status}`, true);
    return null;
  }
  return waitForJob(started.job);
}

// Follows the job with this id until it ends, showing its progress; the job, or null if it failed.
// The server answers ?wait= as soon as the job ends (else after half a second): no polling delay.
async function waitForJob(id) {
  $("progress").hidden = false;
  for (;;) {
    const job = await (await fetch(`/api/job?wait=${id}`)).json();
    api.job = job;
    $("progress").value = job.progress;
    status(`job ${job.id}: ${job.stage}`);
    if (job.id === id && job.state !== "running") {
      $("progress").hidden = true;
      if (job.state === "failed") {
        api.lastRun = job;
        status(`job ${job.id} failed: ${job.error}`, true);
        return null;
      }
      return job;
    }
  }
}

async function runJob(path, model = "default") {
  if (selected < 0) return status("pick a view first", true);
  const form = new FormData();
  if (path === "/api/edit") form.append("model", model);
  form.append("view", api.info.scene.views[selected].name);
  form.append("mask", await maskBlob(), "mask.png");
  // The click or box tool's outline: the server paints its rim over too (a drawn region as it is).
  form.append("selected", viewClicks.length || viewBox ? "1" : "0");
  form.append("mode", $("mode").value);
  form.append("refine", $("refine").value);
  const reference = $("reference-file").files[0];
  if (reference) form.append("reference", reference, reference.name);
  const clicked = performance.now();
  const job = await startAndWait(path, form);
  if (!job) return;
  const jobSeen = performance.now();
  // The splats first: the server writes the masks' PNGs behind its answer.
  if (job.result.splats) {
    afterUrl = job.result.splats;
    await showPly(afterUrl);
    setActive("after");
    setDownloads();
  }
  const splatsDrawn = performance.now();
  await drawMaskOverlays(job.result.masks ?? {});
  const seconds = (splatsDrawn - clicked) / 1000;
  // Where the time from the click went (ms): until the job was seen done, loading and drawing
  // the new splats (the edit's figure ends here), then drawing the masks over the views.
  const parts = { job: jobSeen - clicked, splats: splatsDrawn - jobSeen, masks: performance.now() - splatsDrawn };
  api.lastRun = { ...job, clientSeconds: seconds, parts };
  // Which inpainter painted the reference, when the page sent none.
  const painter = { lama: api.info.inpainter?.network, ns: "OpenCV Navier-Stokes", telea: "OpenCV Telea",
    patch: "patches" }[job.result.reference];
  const released = job.result.model && api.info.networks?.released?.file && job.result.model.endsWith(api.info.networks.released.file);
  status(`job ${job.id} done${released ? " (the released checkpoint)" : ""}: ${job.result.splats ? `${job.result.gaussians} Gaussians, ` : "masks, "}` +
    `${painter ? `the reference painted by ${painter}, ` : ""}${seconds.toFixed(2)} s from the click`);
  showStages(job, parts);
}

// Where the time of the last job went: the server's stages, then the page's own parts.
function showStages(job, parts) {
  const rows = (job.stages ?? []).filter((s) => !s.behind && s.ms >= 0.5);
  rows.push({ stage: "page: request and answer", ms: parts.job - 1000 * job.seconds });
  rows.push({ stage: "page: splats loaded and drawn", ms: parts.splats });
  const cells = rows.map((s) => `<tr><td>${s.stage}${s.calls > 1 ? ` (${s.calls}x)` : ""}</td><td>${Math.max(0, s.ms).toFixed(0)}</td></tr>`);
  cells.push(`<tr><td>then: masks drawn over the views</td><td>${parts.masks.toFixed(0)}</td></tr>`);
  $("stages").innerHTML = `<summary>where the ${(parts.job + parts.splats).toFixed(0)} ms to the splats went</summary><table>${cells.join("")}</table>`;
  $("stages").hidden = false;
}

// Exports of the splats on screen: the orbit video and the evaluation report, as jobs.
async function runExport(kind) {
  if (!api.loadedUrl) return status("no splats on screen", true);
  const job = await startAndWait(`/api/${kind}`, new URLSearchParams({ ply: api.loadedUrl }));
  if (!job) return;
  api.lastRun = job;
  const link = document.createElement("a");
  link.href = job.result.video ?? job.result.report;
  link.target = "_blank";
  link.textContent = kind === "video" ? `orbit video (job ${job.id})` : `eval report (job ${job.id})`;
  $("exports").append(link, " ");
  status(`job ${job.id} done`);
}
// 3D Gaussian splatting of the whole capture (the server's `reconstruct`), for a capture walked
// around its object, which the network predicts only near its reference: the trained splats
// replace those on screen, ready for a click and Fill.
async function runTrain() {
  const job = await startAndWait("/api/train", new URLSearchParams({ length: $("train-length").value }));
  if (!job) return;
  beforeUrl = job.result.splats;
  await showPly(beforeUrl);
  setActive("before");
  setDownloads();
  addPly({ name: `trained splats (job ${job.id})`, url: job.result.splats });
  $("fill-panel").hidden = !api.info.filling;
  const t = job.result.trained;
  status(`job ${job.id} done: ${t.splats} splats trained in ${t.training.steps} steps, ${job.seconds.toFixed(0)} s ` +
    `(PSNR ${t.psnr.toFixed(2)} dB over the training views)`);
  api.lastTrain = job;  // last: the trained splats are on screen by now
}
$("train").onclick = runTrain;
$("video").onclick = () => runExport("video");
$("eval").onclick = () => runExport("eval");
$("preview").onclick = () => runJob("/api/masks");
$("run").onclick = () => runJob("/api/edit");
$("run-released").onclick = () => runJob("/api/edit", "released");

// ---- remove and fill ------------------------------------------------------------------------
// The region: a box (three.js transform handles; Spark hides the splats inside at once), a
// stroke painted over the view on screen, or clicks on objects in it (the server selects their
// splats; shift-click adds). Fill sends it with the splats on screen to the server.
let fillMode = null; // "box" | "paint" | "click"
let fillClicks = []; // "click": the clicks so far, in the canvas's pixels
let fillNotClicks = []; // with a segmenter: the alt-clicks, points that are not the object
let region = null; // the box: {object (centre, turn, scale = size), gizmo, sdf, edit}
// The canvas painted on over the viewer, made when painting first starts.
let fillCanvas = null, fillPaint = null;
function paintingCanvas() {
  if (!fillCanvas) {
    fillCanvas = document.createElement("canvas");
    fillCanvas.id = "fill-canvas";
    viewer.appendChild(fillCanvas);
    fillPaint = attachBrush(fillCanvas, () => false, () => Math.max(4, fillCanvas.width / 40), () => fillMode === "paint");
    fillCanvas.addEventListener("pointerdown", (e) => {
      if (fillMode !== "click") return;
      selectAt(...canvasPixel(fillCanvas, e), e);
    });
  }
  return fillCanvas;
}

// A click on the view on screen: the server selects the object's splats under it (and under the
// clicks before it with shift; with a segmenter, alt-click marks a point that is not the object),
// and the selection is drawn over the view in red.
async function selectAt(x, y, e = {}) {
  if (!api.loadedUrl) return status("no splats on screen", true);
  const [clicks, notClicks] = nextClicks(e, x, y, fillClicks, fillNotClicks);
  const selection = await requestSelection({ ply: api.loadedUrl, camera: JSON.stringify(screenCamera()) }, clicks,
    fillPaint, notClicks);
  if (!selection) return;
  fillClicks = clicks;
  fillNotClicks = notClicks;
  $("fill-result").textContent = `selected ${selection.selected} of ${selection.total} splats (${selection.pixels} ` +
    `pixels on screen) from ${clicks.length} click${clicks.length > 1 ? "s" : ""}; ${selection.clientSeconds.toFixed(2)} s`;
  status(selection.how === "segmenter"
    ? "shift-click adds a point on the object, alt-click marks what is not; Fill removes the selection"
    : "shift-click adds another object; Fill removes the selection");
}

// The clicks as the server reads them: "x,y;x,y".
const clickList = (clicks) => clicks.map(([x, y]) => `${x.toFixed(1)},${y.toFixed(1)}`).join(";");

// Asks the server for the selection under `clicks` (and not at `notClicks`; with `fields`: a
// view's index, or the splats and the camera on screen) and draws it on `ctx` in red:
// api.lastSelect (the answer, the points sent and the seconds from the click), or null when
// refused (the reason shown).
async function requestSelection(fields, clicks, ctx, notClicks = []) {
  const form = new FormData();
  for (const [name, value] of Object.entries(fields)) form.append(name, value);
  form.append("clicks", clickList(clicks));
  if (notClicks.length) form.append("not_clicks", clickList(notClicks));
  const clicked = performance.now();
  const answer = await fetch("/api/select", { method: "POST", body: form });
  const selection = await answer.json();
  if (answer.status !== 200) {
    api.lastSelect = { error: selection.error };
    status(selection.error ?? `error ${answer.status}`, true);
    return null;
  }
  drawRuns(ctx, selection);
  api.lastSelect = { ...selection, clicks: clicks.length,
    sent: { clicks: clickList(clicks), notClicks: clickList(notClicks), box: fields.box ?? "" },
    clientSeconds: (performance.now() - clicked) / 1000 };
  return api.lastSelect;
}

// The server's runs (the view's pixels row by row, alternately outside and inside) in red.
function drawRuns(ctx, { width, height, runs }) {
  ctx.canvas.width = width;
  ctx.canvas.height = height;
  const pixels = ctx.createImageData(width, height);
  let at = 0;
  runs.forEach((length, k) => {
    if (k % 2)
      for (let i = at; i < at + length; ++i) {
        pixels.data[4 * i] = 255;
        pixels.data[4 * i + 3] = 255;
      }
    at += length;
  });
  ctx.putImageData(pixels, 0, 0);
}

function updateRegionPreview() {
  if (!region) return;
  region.sdf.position.copy(region.object.position);
  region.sdf.quaternion.copy(region.object.quaternion);
  region.sdf.scale.copy(region.object.scale).multiplyScalar(0.5);  // Spark's box: half sizes
  region.edit.visible = fillMode === "box" && showingBefore && $("fill-preview").checked;
  region.object.visible = fillMode === "box" && showingBefore;
  region.gizmo.enabled = region.object.visible;
  region.helper.visible = region.object.visible;
  const { position: p, rotation: r, scale: s } = region.object;
  api.fillBox = { centre: p.toArray(), size: s.toArray(), turn: [r.x, r.y, r.z].map(THREE.MathUtils.radToDeg) };
  invalidate();
}

function makeRegionBox() {
  const bounds = mesh.getBoundingBox(true);
  const object = new THREE.Object3D();
  object.rotation.order = "ZYX";  // turned about x, then y, then z, as the server's box
  object.position.copy(bounds.getCenter(new THREE.Vector3()));
  object.scale.copy(bounds.getSize(new THREE.Vector3()).multiplyScalar(0.25));
  const lines = new THREE.LineSegments(new THREE.EdgesGeometry(new THREE.BoxGeometry(1, 1, 1)),
    new THREE.LineBasicMaterial({ color: 0xff3300 }));
  object.add(lines);
  scene.add(object);
  const gizmo = new TransformControls(camera, renderer.domElement);
  gizmo.attach(object);
  const helper = gizmo.getHelper();
  scene.add(helper);
  gizmo.addEventListener("dragging-changed", (e) => controls && (controls.enabled = !e.value));
  gizmo.addEventListener("objectChange", updateRegionPreview);
  gizmo.addEventListener("change", () => invalidate());
  const sdf = new SplatEditSdf({ type: SplatEditSdfType.BOX, opacity: 0 });
  const edit = new SplatEdit({ rgbaBlendMode: SplatEditRgbaBlendMode.MULTIPLY, sdfs: [sdf] });
  scene.add(edit);
  region = { object, gizmo, helper, sdf, edit };
}

// Places the box (scripts and tests; the handles do the same): centre, full size, turn in degrees.
function setFillBox(centre, size, turn = [0, 0, 0]) {
  setFillMode("box");
  region.object.position.fromArray(centre);
  region.object.scale.fromArray(size);
  region.object.rotation.set(...turn.map(THREE.MathUtils.degToRad), "ZYX");
  updateRegionPreview();
}

function setFillMode(mode) {
  fillMode = mode;
  if (mode === "box" && !region) makeRegionBox();
  $("fill-box").classList.toggle("on", mode === "box");
  $("fill-paint").classList.toggle("on", mode === "paint");
  $("fill-click").classList.toggle("on", mode === "click");
  fillClicks = [];
  fillNotClicks = [];
  $("gizmo-modes").hidden = mode !== "box";
  // Painting and clicking hold the camera still: the stroke and the clicks are on the view on screen.
  const onView = mode === "paint" || mode === "click";
  if (onView) paintingCanvas();
  if (fillCanvas) fillCanvas.hidden = !onView;
  $("fill-reference-row").hidden = !onView;
  if (controls) controls.enabled = !onView;
  if (onView) {
    fillCanvas.width = renderer.domElement.width;
    fillCanvas.height = renderer.domElement.height;
    fillCanvas.style.width = renderer.domElement.style.width || `${viewer.clientWidth}px`;
    fillCanvas.style.height = renderer.domElement.style.height || `${viewer.clientHeight}px`;
    fillPaint.clearRect(0, 0, fillCanvas.width, fillCanvas.height);
  }
  updateRegionPreview();
}
$("fill-box").onclick = () => setFillMode(fillMode === "box" ? null : "box");
$("fill-paint").onclick = () => setFillMode(fillMode === "paint" ? null : "paint");
$("fill-click").onclick = () => {
  setFillMode(fillMode === "click" ? null : "click");
  // The server reads the splats now, not at the first click (1.2 M splats: 0.2 s and more).
  if (fillMode === "click" && api.loadedUrl) {
    const form = new FormData();
    form.append("ply", api.loadedUrl);
    fetch("/api/select", { method: "POST", body: form }).catch(() => {});
  }
};
$("fill-preview").onchange = updateRegionPreview;
for (const mode of ["translate", "scale", "rotate"])
  $(`gizmo-${mode}`).onclick = () => {
    region?.gizmo.setMode(mode);
    for (const m of ["translate", "scale", "rotate"]) $(`gizmo-${m}`).classList.toggle("on", m === mode);
  };

// Where a point of the scene is on screen, in the viewer's CSS pixels (scripts and tests).
function screenPoint(point) {
  const v = new THREE.Vector3(...point).project(camera);
  const r = renderer.domElement.getBoundingClientRect();
  return [((v.x + 1) / 2) * r.width, ((1 - v.y) / 2) * r.height];
}

// The view on screen as a camera list of one (render --cameras' JSON: c2w rows, OpenGL axes).
function screenCamera() {
  const width = fillCanvas.width, height = fillCanvas.height;
  const fy = height / (2 * Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2));
  camera.updateMatrixWorld(true);
  const m = camera.matrixWorld.clone().transpose().toArray();
  const c2w = [0, 4, 8, 12].map((k) => m.slice(k, k + 4));
  return { convention: "opengl", cameras: [{ name: "page view", width, height, fx: fy, fy, cx: width / 2, cy: height / 2, c2w }] };
}

async function runFill() {
  if (!api.loadedUrl) return status("no splats on screen", true);
  const form = new FormData();
  form.append("ply", api.loadedUrl);
  form.append("refine", $("fill-refine").value);
  form.append("inpainter", $("fill-inpainter").value);
  if (fillMode === "box" && region) {
    const { centre, size, turn } = api.fillBox;
    form.append("box", [...centre, ...size, ...turn].map((v) => +v.toPrecision(7)).join(","));
  } else if (fillMode === "paint" || (fillMode === "click" && fillClicks.length)) {
    form.append("camera", JSON.stringify(screenCamera()));
    if (fillMode === "click") {
      form.append("clicks", clickList(fillClicks));
      if (fillNotClicks.length) form.append("not_clicks", clickList(fillNotClicks));
    } else form.append("mask", await maskBlob(fillCanvas), "mask.png");
    const reference = $("fill-reference").files[0];
    if (reference) form.append("reference", reference, reference.name);
  } else {
    return status("place a box (box), paint over the object (paint) or click on it (click) first", true);
  }
  const clicked = performance.now();
  const job = await startAndWait("/api/fill", form);
  if (!job) return;
  const before = api.loadedUrl;
  afterUrl = job.result.splats;
  if (!beforeUrl) beforeUrl = before;
  setActive("after");
  await showPly(afterUrl);
  setDownloads();
  if (fillMode === "paint" || fillMode === "click") fillPaint.clearRect(0, 0, fillCanvas.width, fillCanvas.height);
  fillClicks = [];
  fillNotClicks = [];
  const seconds = (performance.now() - clicked) / 1000;
  const f = job.result.fill;
  api.lastFill = { ...job, clientSeconds: seconds };
  const painter = f.inpainter === "given" ? "your reference" : f.inpainter === "lama" ? api.info.inpainter.network : f.inpainter;
  $("fill-result").innerHTML = `${f.removed} splats removed, ${f.added} added, the hole painted by ${painter}; ` +
    `${seconds.toFixed(2)} s (<a href="${f.report}" target="_blank">fill.json</a>)`;
  status(`job ${job.id} done: filled (${f.cameras})`);
  showStages(job, { job: performance.now() - clicked, splats: 0, masks: 0 });
}
$("fill-run").onclick = runFill;

// The view on screen and the painted region, each a PNG of the canvas's size, downloaded: a 2D
// inpainter paints the region out of the view, and that picture comes back as the reference.
async function saveViewAndMask() {
  if (!fillCanvas) return status("paint over the object first", true);
  renderer.render(scene, camera);  // the drawing buffer holds the view as it is now
  const view = await new Promise((done) => renderer.domElement.toBlob(done, "image/png"));
  const mask = await maskBlob(fillCanvas);
  for (const [blob, name] of [[view, "view.png"], [mask, "mask.png"]]) {
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = name;
    a.click();
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
  }
  status(`saved view.png and mask.png (${fillCanvas.width}x${fillCanvas.height}): paint the region out of the view, ` +
    "then give the picture as the inpainted reference");
}
$("fill-save").onclick = saveViewAndMask;

// Which networks the page runs and, for each one absent, the command that brings it.
function showNetworks(networks) {
  if (!networks) return;
  const from = (n) => (n.from === "the cache" ? " (from the cache)" : n.from === "built in" ? " (built in)" : "");
  const parts = [];
  const seg = networks.segmenter;
  parts.push(seg.missing ? `click: ${seg.instead}` : `click: ${seg.network}${from(seg)}`);
  const inp = networks.inpainter;
  parts.push(inp.missing ? `hole: ${{ ns: "OpenCV Navier-Stokes", telea: "OpenCV Telea", patch: "patches" }[inp.instead] ?? inp.instead}`
    : `hole: ${inp.network}${from(inp)}`);
  if (networks.model) parts.push(`model: ${networks.model.from === "built in" ? "the built-in model" : networks.model.file}${from(networks.model)}`);
  const label = { "mobile-sam": "a segmenter (MobileSAM)", "big-lama": "LaMa", instainpaint: "the released checkpoint" };
  const missing = [seg, inp, networks.released].filter((n) => n?.missing).map((n) => n.get.split(" ").pop());
  let html = `networks: ${parts.join(" · ")}`;
  if (missing.length)
    html += `<br>not in the cache: ${missing.map((m) => label[m] ?? m).join(", ")}; ` +
      `<code>instainpaint models get ${missing.join(" ")}</code> brings ${missing.length > 1 ? "them" : "it"} (then serve again)`;
  $("networks").innerHTML = html;
  if (networks.released?.offered) {
    $("run-released").hidden = false;
    $("run-released").textContent = `Run with the released checkpoint (about ${networks.released.seconds_estimate} s)`;
  }
}

// ---- start -------------------------------------------------------------------------------
async function start() {
  const info = await (await fetch("/api/info")).json();
  api.info = info;
  showNetworks(info.networks);
  const views = info.scene?.views ?? [];
  const viewIndex = params.has("view") ? Number(params.get("view")) : -1;
  if (exact && views[viewIndex]) exactView = views[viewIndex];
  resize();
  addFrustums(views);
  listPlys(info.plys);
  $("video").disabled = !info.scene;
  $("eval").disabled = !info.scene?.test_views;
  listViews(views);
  if (views.length && !exact) {
    camera.up.copy(sceneUp(views));
    api.sceneUp = camera.up.toArray();
    makeControls();
  }
  // Opened on a view: the one asked for, else the capture's first (the splats are in its sight).
  if (viewIndex >= 0 && views[viewIndex]) jumpToView(viewIndex);
  else if (views.length) jumpToView(0);
  const asked = params.get("ply") ?? "0";
  let first = /^\/api\/jobs\/\d+\/gaussians\.(ply|spz)$/.test(asked) ? { name: asked, url: asked } : info.plys[Number(asked)];
  // Opened on a scene alone: the server reconstructs it (object kept) at start; show it in 3D
  // when it is ready, and open the editor on the view the network took as its reference.
  let reconstruction = null;
  if (!first && info.job?.kind === "reconstruct") {
    $("hud").textContent = "reconstructing the scene ...";
    reconstruction = await waitForJob(info.job.id);
    if (reconstruction?.result?.splats)
      first = { name: "the scene as captured", url: reconstruction.result.splats };
  }
  if (first) {
    beforeUrl = first.url;
    await showPly(first.url);
    setActive("before");
    setDownloads();
  }
  if (reconstruction?.result?.splats) listPlys([first]);  // not "none given": the scene's own
  $("fill-panel").hidden = !info.filling || !first;
  $("train-panel").hidden = !info.scene;
  if (info.inpainter?.name === "lama") {  // serve --inpainter: LaMa paints Run's reference and Fill's hole
    $("reference-default").textContent = `(none: ${info.inpainter.network})`;
    const lama = document.createElement("option");
    lama.value = "lama";
    lama.textContent = `${info.inpainter.network} (learned)`;
    $("fill-inpainter").prepend(lama);
    $("fill-inpainter").value = "lama";
  }
  const reference = views.findIndex((v) => v.name === reconstruction?.result?.reference_view);
  if (reference >= 0 && !exact) selectView(reference);
  $("hud").textContent = first ? first.name : "no splats: serve --ply FILE, or run an edit";
  if (exact) $("hud").hidden = true;
}
api.ready = start().catch((e) => {
  status(String(e), true);
  $("hud").textContent = `error: ${e}`;
  throw e;
});
