"""instainpaint: remove, replace or insert an object in a 3D scene from one edited photo.

A thin layer over the C++ library that the `instainpaint` command uses (same code, same
results, byte for byte). A scene's few posed photos, its object masks and one photo edited
by any 2D inpainter go through a transformer that predicts one 3D Gaussian per input pixel;
the Gaussians render the edited scene from any camera.

    import instainpaint as ii

    scene = ii.load_scene("statue", hold_out_every=8)      # LLFF/SPIn-NeRF, nerfstudio, COLMAP
    predictor = ii.Predictor()                              # "auto": the cache's released checkpoint, else built in
    gaussians = predictor.predict(scene, reference="inpainted.png")
    gaussians = gaussians.refine(scene, preset="fast", progress=print)
    gaussians.save("statue.spz")                            # .ply, .compressed.ply, .spz, .sog
    rgb = gaussians.render(scene.camera(scene.test_views[0], height=256))  # H x W x 3 float32

Arrays come out as NumPy arrays over the library's memory, without a copy; hand them to
torch.from_dlpack (or JAX, CuPy) for a tensor over the same memory. Arrays go in as anything
with the buffer protocol or DLPack (NumPy, torch, ...), float in [0, 1] or uint8.
Errors raise `instainpaint.Error` (a RuntimeError) with the library's message. Long calls
release the GIL. The library logs its progress to standard output; set_log_level("warning")
quiets it.
"""
from __future__ import annotations

import inspect
import json
import os
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

from . import _core, models
from ._core import Camera, Error, Scene, set_log_level, set_threads


def _geometry_value(kind: str, text: str) -> Any:
    if kind == "bool":
        return text == "true"
    if kind == "number":
        return float(text)
    if kind == "integer":
        return int(text)
    return text


# Predictor.predict's geometry keywords: the commands' geometry flags, one row each of the
# library's table (geometry/settings.h), with its kind, its default (the commands'), its choices
# and its help: a setting added there is a keyword here.
_GEOMETRY = {name: (kind, _geometry_value(kind, default), choices, help)
             for name, kind, default, choices, help in _core._geometry_settings}
# Keywords renamed, kept as aliases: flying_pixels_far=True/False is flying_pixels="far"/"keep".
_GEOMETRY_ALIASES = {"flying_pixels_far": ("flying_pixels", lambda far: "far" if far else "keep")}


def _geometry_texts(geometry: Mapping[str, Any]) -> Dict[str, str]:
    """Predictor.predict's geometry keywords as the library's table reads them (text)."""
    texts = {}
    for name, value in geometry.items():
        if name in _GEOMETRY_ALIASES:
            name, convert = _GEOMETRY_ALIASES[name]
            value = convert(value)
        if name not in _GEOMETRY:
            raise TypeError(f"predict() got an unexpected keyword argument '{name}' (the geometry's: "
                            + ", ".join(_GEOMETRY) + ")")
        kind = _GEOMETRY[name][0]
        texts[name] = ("true" if value else "false") if kind == "bool" else str(value)
    return texts


__all__ = [
    "Camera", "Error", "Gaussians", "Predictor", "Scene", "evaluate", "load_gaussians", "load_scene",
    "masks_from_one", "reconstruct", "select", "Segmenter", "set_log_level", "set_threads",
]
__version__ = "0.1.0"

PathLike = Union[str, "os.PathLike[str]"]


def _path(p: Optional[PathLike]) -> Optional[str]:
    return None if p is None else os.fspath(p)


def load_scene(path: PathLike, *, masks: Optional[PathLike] = None, hold_out_every: int = 0,
               keep_object: bool = False, format: str = "auto", images: str = "") -> Scene:
    """Reads a scene folder: LLFF/SPIn-NeRF, nerfstudio or COLMAP (detected when format="auto").

    masks: a folder of object masks, matched to the views by file stem (else the scene's own).
    hold_out_every: N > 0 holds input views 0, N, 2N, ... out as test views (3DGS's protocol).
    keep_object: with hold_out_every, a reconstruction (held-out views are compared whole).
    images: the image sub-folder to read (e.g. "images_4"); empty = the format's default.
    """
    return _core._load_scene(os.fspath(path), format, images, _path(masks), hold_out_every, keep_object)


ProgressCallback = Callable[[Dict[str, Any]], Any]


class Gaussians:
    """3D Gaussians: one per input pixel from a prediction, or read from a splat file.

    Attributes (NumPy arrays over the library's memory): means (N, 3), quats (N, 4; w, x, y, z),
    scales (N, 3), opacities (N,), colors (N, 3) RGB or (N, K, 3) spherical harmonics.
    A prediction's arrays live in the frame the network normalised the scene's poses to; render()
    takes the scene's own cameras and save() writes the scene's own frame, as `instainpaint
    infer` does, so that the file lines up with the capture and other tools' splats.
    """

    def __init__(self, core: "_core.Gaussians"):
        self._g = core

    def __len__(self) -> int:
        return len(self._g)

    def __repr__(self) -> str:
        return f"Gaussians({len(self)} on {self.device}, sh_degree={self.sh_degree})"

    means = property(lambda self: self._g.means, doc="(N, 3) positions")
    quats = property(lambda self: self._g.quats, doc="(N, 4) rotations as quaternions (w, x, y, z)")
    scales = property(lambda self: self._g.scales, doc="(N, 3) standard deviations")
    opacities = property(lambda self: self._g.opacities, doc="(N,) opacities in (0, 1)")
    colors = property(lambda self: self._g.colors, doc="(N, 3) RGB, or (N, K, 3) SH coefficients")
    sh_degree = property(lambda self: self._g.sh_degree, doc="-1 for RGB colours, else the SH degree")
    device = property(lambda self: self._g.device, doc='"cpu" or "cuda:N"')
    context = property(lambda self: list(self._g.context),
                       doc="the views the network saw, reference first (empty for a file)")

    @property
    def geometry(self) -> Optional[dict]:
        """Where a prediction's depth was scaled to: the scene's points' source and each context
        view's factor (the run.json "geometry" of `instainpaint infer`), or None for a file."""
        text = self._g._geometry
        return json.loads(text) if text else None

    @property
    def refine_report(self) -> Optional[dict]:
        """What the refinement that made these did (steps, time, loss, densification), or None."""
        text = self._g._refine_report
        return json.loads(text) if text else None

    @property
    def reconstruct_report(self) -> Optional[dict]:
        """What the reconstruction that made these did (start, steps, splats, scores), or None."""
        text = self._g._reconstruct_report
        return json.loads(text) if text else None

    def save(self, path: PathLike, *, normalized: bool = False) -> None:
        """Writes a splat file, the format by name: .ply, .compressed.ply, .spz, .sog or meta.json,
        in the scene's frame (normalized=True: the network's pose-normalised one, as the arrays)."""
        self._g.save(os.fspath(path), normalized)

    def render(self, camera: Camera, *, background: Sequence[float] = (1.0, 1.0, 1.0), depth: bool = False):
        """Renders the Gaussians seen by `camera` (in the scene's frame): H x W x 3 float32 RGB;
        with depth=True also the H x W expected depth (0 where nothing was hit)."""
        rgb, z = self._g._render(camera, tuple(float(c) for c in background))
        return (rgb, z) if depth else rgb

    def subset(self, keep) -> "Gaussians":
        """The Gaussians where keep (a bool array, one per Gaussian: select()'s answer) is true, in the
        same frame."""
        import numpy as np
        return Gaussians(self._g._subset(np.ascontiguousarray(keep, dtype=bool)))

    def render_video(self, scene: Scene, path: PathLike, *, trajectory: str = "orbit", frames: int = 48,
                     height: int = 256, fps: int = 24, progress: Optional[Callable[[int, int], Any]] = None) -> None:
        """Renders a camera path around `scene` to an MP4 video (ffmpeg): "orbit" (the official
        orbit around the scene's cameras, square frames), "path" (a smooth path through the
        views) or "views" (the views' own cameras). progress(done, total) after each frame."""
        self._g._render_video(scene, os.fspath(path), trajectory, frames, height, fps, progress)

    def refine(self, scene: Scene, *, preset: str = "balanced", sh_degree: int = 0,
               position_rate: Optional[float] = None, exposure: bool = False,
               progress: Optional[ProgressCallback] = None) -> "Gaussians":
        """Optimises a prediction against every view of its scene (3DGS-style, with densification)
        and returns the refined Gaussians; these stay as they are. The region keeps the
        prediction's splats, each view's mask is fitted to what the prediction draws there, and
        every 8th input view is held out to choose the result: the prediction itself comes back
        when no iterate beats it there.

        preset: "fast" (1 minute), "balanced" (9), "best" (20), a time ("90s", "2m") or a step count.
        position_rate: the position learning rate in multiples of 3DGS's (default 30).
        progress: called after each step with {"step", "fraction", "loss", "eta_s", "gaussians"};
        an exception it raises stops the refinement and propagates.
        """
        call = None
        if progress is not None:
            def call(step, fraction, loss, eta_s, count):
                progress({"step": step, "fraction": fraction, "loss": loss, "eta_s": eta_s, "gaussians": count})
        return Gaussians(self._g._refine(scene, str(preset), sh_degree, position_rate, exposure, call))


    def select(self, camera: Camera, click, *, view: str = "the camera", not_click=None,
               segmenter: Union["Segmenter", str, None] = "auto"):
        """The splats of the object under click=(x, y) (pixels of camera's view; a list of points adds
        more), as `fill --click` selects them: a bool array, one per splat. With a segmenter (the
        default "auto": the cache's, when there is one; None: none), the object it outlines in these
        splats' render from the camera (not_click= points that are not it)."""
        import numpy as np
        s = _segmenter_of(segmenter)
        return np.asarray(_core._select_splats(self._g, camera, view, _clicks(click), _clicks(not_click),
                                               s._s if s else None), dtype=bool)

    @property
    def fill_report(self) -> Optional[dict]:
        """What the fill that made these did (splats removed and added, cameras, stage times), or None."""
        text = self._g._fill_report
        return json.loads(text) if text else None

    def fill(self, *, box: Optional[Sequence[float]] = None, selection: Optional["Gaussians"] = None,
             view: Optional[str] = None, mask: Union[PathLike, Any, None] = None, click=None,
             scene: Optional[Scene] = None, cameras: Optional[Mapping[str, Camera]] = None,
             reference: Union[PathLike, Any, None] = None, reference_view: Optional[str] = None,
             views: int = 4, height: int = 256, up: Optional[Sequence[float]] = None,
             refine: Optional[str] = None, all_views: bool = False, placement: str = "surface",
             inpainter: str = "", predictor: Optional["Predictor"] = None) -> "Gaussians":
        """Removes a region and fills the hole it leaves, as `instainpaint fill`; returns new
        Gaussians in the scene's frame (these stay as they are), every other splat as it was.

        The region, one of: box=(cx, cy, cz, sx, sy, sz[, rx, ry, rz]) in the scene's frame;
        selection= the same Gaussians with the region deleted; view= a camera's name and mask= a
        stroke over the object on it (an H x W array or a file), click=(x, y) on the object (a
        list of points adds more) or box=(x0, y0, x1, y1) around it in that camera's pixels (GrabCut
        in the render from it). Cameras: scene= (its views and
        object-free test views) and/or
        cameras= {name: Camera}; none: automatic views around the region (up= the scene's up).
        reference= the reference view's hole painted by any 2D inpainter (array or file), for
        reference_view= (default: view=); refine= "fast", "90s", a step count... optimises the new
        splats alone. placement="surface" (default) continues the scene's surface around the hole
        and places the reference's pixels on it; "network" takes the network's Gaussians of the
        hole (all_views=True: of every chosen view's hole, not the reference's alone).
        inpainter= without reference=, the 2D inpainter of the reference's hole: "telea", "ns",
        "patch" (patches copied inward: texture continues, no smear), "big-lama" (the cache's LaMa) or
        a LaMa file; default $INSTAINPAINT_INPAINTER, else "auto": the cache's LaMa, else "ns".
        predictor: default the built-in model on the best device.
        """
        given: Dict[str, Camera] = {}
        if scene is not None:
            for name in [*scene.views, *scene.test_views]:
                given[name] = scene.camera(name)
        given.update(cameras or {})
        if predictor is None:
            predictor = Predictor()
        return Gaussians(_core._fill(
            self._g, None if box is None else [float(v) for v in box],
            None if selection is None else selection._g, view or "", mask, _clicks(click), given, reference,
            reference_view or "", views, height, None if up is None else [float(v) for v in up],
            "" if refine is None else str(refine), all_views, placement, os.fspath(inpainter), predictor._p))


def reconstruct(scene: Scene, *, preset: str = "balanced", steps: Optional[int] = None, height: int = 0,
                eval: bool = False, max_splats: int = 1500000, sh_degree: int = 3, seed: int = 0,
                start: Optional["Gaussians"] = None, device: str = "auto",
                lpips_vgg: Optional[PathLike] = None,
                progress: Optional[ProgressCallback] = None) -> "Gaussians":
    """3D Gaussian splatting of the whole capture (as `instainpaint reconstruct`), in its own frame.

    Starts from the scene's COLMAP points, else points triangulated from its photos (or from
    `start`). preset: "fast" (1 minute), "balanced" (9), "best" (20) or a time ("90s"); steps: a
    number of steps instead. height: rows trained on (0: the photos' own, at most 1600 on the long
    side). eval: score the held-out views: load the scene with hold_out_every=8, keep_object=True.
    The scores, splat counts and seconds are in the result's reconstruct_report; LPIPS (VGG) too with
    lpips_vgg, torchvision's vgg16-397923af.pth (default: $INSTAINPAINT_LPIPS_VGG).
    progress: called after each step with {"step", "fraction", "loss", "eta_s", "gaussians"}.
    """
    call = None
    if progress is not None:
        def call(step, fraction, loss, eta_s, count):
            progress({"step": step, "fraction": fraction, "loss": loss, "eta_s": eta_s, "gaussians": count})
    return Gaussians(_core._reconstruct(scene, str(preset), -1 if steps is None else int(steps), height, eval,
                                        max_splats, sh_degree, seed, None if start is None else start._g,
                                        device, "" if lpips_vgg is None else os.fspath(lpips_vgg), call))


def load_gaussians(path: PathLike) -> Gaussians:
    """Reads a splat file (.ply, .compressed.ply, .spz, .sog or meta.json) in its own frame."""
    return Gaussians(_core._read_splats(os.fspath(path)))


class Predictor:
    """A model loaded once, predicting as often as needed.

    checkpoint: None or "auto" (the cache's released checkpoint, ii.models.get("instainpaint"),
    else the model built into the library), "default" (the built-in model), or a file (the
    released InstaInpaint .pth, a safetensors file). device: "auto" (a GPU when there is one), "cpu", "cuda", "cuda:N".
    precision: "auto" (bf16 on a GPU and on CPUs with native bf16), "fp32" or "bf16".
    """

    def __init__(self, checkpoint: Optional[PathLike] = None, *, device: str = "auto", precision: str = "auto"):
        self._p = _core.Predictor(_path(checkpoint) or "", device, precision)

    model = property(lambda self: self._p.model, doc="the checkpoint's file, or the built-in model's name")
    device = property(lambda self: self._p.device)
    precision = property(lambda self: self._p.precision)

    @property
    def config(self) -> dict:
        """The model's configuration (layers, widths, patch size, ...)."""
        return json.loads(self._p._describe)["config"]

    def __repr__(self) -> str:
        return f"Predictor({self.model!r}, device={self.device!r}, precision={self.precision!r})"

    def predict(self, scene: Scene, *, context: Sequence[str] = (), views: int = 4,
                reference: Union[PathLike, Any, None] = None, reference_view: str = "", height: int = 256,
                masks: Optional[Mapping[str, Any]] = None, keep_object: bool = False, inpainter: str = "",
                **geometry: Any) -> Gaussians:
        """Predicts the inpainted scene's Gaussians in one forward pass.

        context: view names, reference first (default: `views` views chosen around the reference).
        reference: the 2D-inpainted reference photo, a file or an H x W x 3 array (default: the
        reference view painted by `inpainter`).
        inpainter: without reference=, what paints the reference view's region: "ns", "telea",
        "patch", "big-lama" (the cache's LaMa: a learned inpainter, far better than the classical
        ones) or a LaMa file; default $INSTAINPAINT_INPAINTER, else "auto": the cache's LaMa, else "ns".
        height: the working height in pixels (a multiple of the patch size after scaling).
        masks: object masks by view name (H x W arrays at the photos' size), instead of the scene's.
        keep_object: reconstruct the scene as captured (no masks, the reference's own photo).
        **geometry: what is done with the network's output, one keyword per geometry flag of the
        commands (frame_margin for `--frame-margin`), each with the commands' default; listed below.
        """
        if reference is not None and (isinstance(reference, str) or hasattr(reference, "__fspath__")):
            reference = os.fspath(reference)
        return Gaussians(self._p._predict(scene, list(context), views, reference, reference_view, height,
                                          keep_object, dict(masks or {}), _geometry_texts(geometry),
                                          os.fspath(inpainter)))


def _with_geometry_keywords(predict: Callable) -> None:
    """predict's signature and help list the geometry's keywords, from the library's table."""
    params = [p for p in inspect.signature(predict).parameters.values() if p.kind != p.VAR_KEYWORD]
    params += [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default)
               for name, (kind, default, choices, help) in _GEOMETRY.items()]
    predict.__signature__ = inspect.Signature(params, return_annotation="Gaussians")
    lines = []
    for name, (kind, default, choices, help) in _GEOMETRY.items():
        flag = "--" + name.replace("_", "-")
        lines.append(f"        {name} (`{flag}`, default {default!r}): {help}")
    lines.append("        flying_pixels_far: the older name of flying_pixels (True: \"far\", False: \"keep\").")
    predict.__doc__ = predict.__doc__.rstrip() + "\n\n        Geometry keywords:\n" + "\n".join(lines) + "\n"


_with_geometry_keywords(Predictor.predict)


def masks_from_one(scene: Scene, view: str, region: Union[PathLike, Any], *,
                   predictor: Optional[Predictor] = None, height: int = 256,
                   views: int = 4) -> Tuple[Dict[str, Any], dict]:
    """Masks for every view of the scene from one region marked on one view (`instainpaint masks`).

    region: a mask file or an H x W array at the view's photo size (> 0.5 = marked).
    The region is lifted to 3D with the scene's COLMAP points when it has them, else with the
    predictor's depth (pass one). Returns ({view name: H x W float32 mask}, a report of how).
    """
    if isinstance(region, str) or hasattr(region, "__fspath__"):
        region = os.fspath(region)
    masks, report = _core._masks_from_one(scene, view, region, [], [], None, predictor._p if predictor else None,
                                          height, views)
    return masks, json.loads(report)


def _clicks(click) -> List[Tuple[float, float]]:
    """(x, y) or a list of them, as (float, float) pairs."""
    if click is None:
        return []
    points = [click] if len(click) == 2 and all(isinstance(v, (int, float)) for v in click) else list(click)
    out = []
    for p in points:
        if len(p) != 2:
            raise ValueError(f"click: {p!r} is not a point (x, y)")
        out.append((float(p[0]), float(p[1])))
    return out


class Segmenter:
    """A promptable segmentation network, SAM or MobileSAM, read from the file its authors publish
    (MobileSAM's mobile_sam.pt; SAM's sam_vit_b_01ec64.pth, sam_vit_l_0b3195.pth, sam_vit_h_4b8939.pth),
    never executed. path: "auto" (the cache's, MobileSAM first: ii.models.get("mobile-sam")), a
    catalogue name ("sam-vit-b") or a file. precision: "auto" (bf16 where the CPU has native bf16),
    "fp32" or "bf16"."""

    def __init__(self, path: PathLike = "auto", *, precision: str = "auto"):
        self._s = _core.Segmenter(os.fspath(path), precision)

    @property
    def file(self) -> str:
        return self._s.file

    @property
    def description(self) -> str:
        return self._s.description

    @property
    def precision(self) -> str:
        return self._s.precision

    def segment(self, image, click, *, not_click=None) -> Tuple[Any, dict]:
        """The object under click=(x, y) (or a list of points on it) in image (H x W x 3, uint8 or
        float in [0, 1]); not_click= points that are not the object. One click asks for the network's
        three masks and keeps the best-scored. Returns (H x W float32 mask, a report: the scores, the
        mask chosen)."""
        mask, report = self._s._segment(image, _clicks(click), _clicks(not_click))
        return mask, json.loads(report)


def _segmenter_of(segmenter: Union[Segmenter, str, None]) -> Optional[Segmenter]:
    """A segmenter= keyword: a Segmenter, "auto" (the cache's when there is one, else none), None or "none"."""
    if segmenter is None or segmenter == "none":
        return None
    if isinstance(segmenter, Segmenter):
        return segmenter
    if segmenter == "auto":
        return Segmenter() if models.list()["auto"]["segmenter"] else None
    return Segmenter(segmenter)


def select(scene: Scene, view: str, click=None, *, box: Optional[Sequence[float]] = None, not_click=None,
           segmenter: Union[Segmenter, str, None] = "auto", predictor: Optional[Predictor] = None, height: int = 512,
           views: int = 4) -> Tuple[Dict[str, Any], dict]:
    """The object under a click, or in a box, masked in every view (`instainpaint masks --click` / `--box`).

    box: (x0, y0, x1, y1) around the object in pixels of the view's photo: without a segmenter GrabCut
    finds the object in it by colour (click= points in it are the object, not_click= points are not);
    with one, the box prompts it.
    click: (x, y) in pixels of the view's photo as stored, or a list of such points. With a segmenter
    (a Segmenter, a catalogue name or file, or the default "auto": the cache's when there is one; None: none), its mask of the clicked view (not_click= points that are not the object) is lifted
    to every view and carved; without, each click's object is grown by colour in the network's
    reconstruction of the scene (predictor: default the built-in model) and each view's mask carved
    to it. Returns ({view name: H x W float32 mask}, a report: how the clicked view's mask was made,
    the carved views).
    """
    if click is None and box is None:
        raise ValueError("select: give click=(x, y) on the object or box=(x0, y0, x1, y1) around it")
    if box is not None and len(box) != 4:
        raise ValueError(f"box: {box!r} is not (x0, y0, x1, y1)")
    if predictor is None:
        predictor = Predictor()
    s = _segmenter_of(segmenter)
    masks, report = _core._masks_from_one(scene, view, None, _clicks(click), _clicks(not_click),
                                          s._s if s else None, predictor._p, height, views,
                                          None if box is None else tuple(float(v) for v in box))
    return masks, json.loads(report)


def evaluate(scene: PathLike, out: PathLike, *, method: str = "model", checkpoint: Optional[PathLike] = None,
             gaussians: Optional[PathLike] = None, reference: Optional[PathLike] = None, context: Sequence[str] = (),
             views: int = 4, height: int = 512, hold_out_every: int = 0, keep_object: bool = False,
             refine: str = "", device: str = "auto", report: bool = True) -> dict:
    """The evaluation protocol of `instainpaint eval`: renders every test view, writes `out`
    (renders, metrics.json, a report) and returns metrics.json's content.

    method: "model" (the network: `checkpoint`, None = built-in; or `gaussians`, a splat file),
    "telea" or "mean-fill" (2D baselines). refine: a --refine setting ("fast", "90s", ...).
    """
    text = _core._evaluate(os.fspath(scene), os.fspath(out), method, _path(checkpoint), _path(gaussians),
                           _path(reference), list(context), views, height, hold_out_every, keep_object, str(refine),
                           device, report)
    return json.loads(text)
