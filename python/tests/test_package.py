"""The Python package against the library's own behaviour: the CLI's bytes, zero-copy arrays,
clear errors, no leaks, progress, the GIL released."""
import gc
import inspect
import json
import os
import pathlib
import resource
import subprocess
import sys
import threading
import zipfile

import numpy as np
import pytest

import instainpaint as ii

REPO = pathlib.Path(__file__).resolve().parents[2]
HEIGHT = 64  # small, so that each prediction takes a fraction of a second on 2 cores


def test_prediction_saved_from_python_equals_the_clis_bytes(tmp_path, cli, statue_dir, statue, predictor):
    # One thread on both sides: PyPI's LibTorch splits a matrix product over two threads differently
    # from run to run (1 run in 10-30 on 2 cores: last bits of one head), one thread never does.
    subprocess.run([str(cli), "infer", "--scene", str(statue_dir), "--height", str(HEIGHT), "--device", "cpu",
                    "--precision", "fp32", "--threads", "1", "--splats", "gaussians.ply,gaussians.spz",
                    "--out", str(tmp_path / "cli")], check=True, capture_output=True)
    ii.set_threads(1)
    try:
        g = predictor.predict(statue, height=HEIGHT)
    finally:
        ii.set_threads(0)
    g.save(tmp_path / "python.ply")
    g.save(tmp_path / "python.spz")
    assert (tmp_path / "python.ply").read_bytes() == (tmp_path / "cli" / "gaussians.ply").read_bytes()
    assert (tmp_path / "python.spz").read_bytes() == (tmp_path / "cli" / "gaussians.spz").read_bytes()
    run = json.loads((tmp_path / "cli" / "run.json").read_text())
    assert g.context == run["context"]


def test_attributes_are_arrays_over_the_librarys_memory(statue, predictor):
    g = predictor.predict(statue, height=HEIGHT)
    n = len(g)
    photo = statue.camera(statue.views[0])
    width = photo.width * HEIGHT // photo.height // 8 * 8
    margin = round(HEIGHT / 8)  # Gaussians past each frame's edges, an eighth of its height
    outer = round(HEIGHT / 4)  # then to a quarter one per 2 x 2 block (the sizes here are even)
    blocks = ((width + 2 * outer) // 2 * ((HEIGHT + 2 * outer) // 2)
              - (width + 2 * margin) // 2 * ((HEIGHT + 2 * margin) // 2))
    cover = g.geometry["region_cover"]  # flat splats over the reference's region, one per pixel of it
    assert cover["opacity"] == 0.3 and cover["gaussians"] > 0, cover
    # The region's own pixels (its mask grown by one) put on the photos' surface around it, in place.
    surface = g.geometry["region_surface"]
    assert surface["opacity"] == 0.95 and surface["slopes"] is False and surface["ring"] > 0, surface
    assert surface["gaussians"] >= cover["gaussians"], (surface, cover)  # the mask grown by a pixel
    dropped = g.geometry["frame_margin"]["dropped"]  # the margin's Gaussians another view sees through
    behind = g.geometry["behind_edges"]["gaussians"]  # the far side of depth edges under the near side
    assert n == 4 * ((width + 2 * margin) * (HEIGHT + 2 * margin) + blocks) - dropped + behind + cover["gaussians"]
    bare = predictor.predict(statue, height=HEIGHT, frame_margin=0, region_cover=0, behind_edges=0)
    assert len(bare) == 4 * HEIGHT * width
    for name, shape in [("means", (n, 3)), ("quats", (n, 4)), ("scales", (n, 3)), ("opacities", (n,)),
                        ("colors", (n, 3))]:
        a = getattr(g, name)
        assert isinstance(a, np.ndarray) and a.dtype == np.float32 and a.shape == shape, name
        assert np.isfinite(a).all(), name
    # Two reads are two views of the same memory: nothing was copied.
    assert np.shares_memory(g.means, g.means)
    assert g.means.ctypes.data == g.means.ctypes.data
    assert g.sh_degree == -1 and g.device == "cpu"


def test_a_gpu_prediction_hands_its_gaussians_over_on_the_gpu(statue):
    torch = pytest.importorskip("torch")
    if not torch.cuda.is_available():
        pytest.skip("no CUDA device here: the GPU build on a lent machine runs this")
    g = ii.Predictor(device="cuda").predict(statue, height=HEIGHT)
    assert g.device.startswith("cuda")
    means = g.means
    assert means.__dlpack_device__()[0] == 2  # kDLCUDA: the array is the device's memory, no host copy
    t = torch.from_dlpack(means)
    assert t.is_cuda and tuple(t.shape) == (len(g), 3)
    assert torch.from_dlpack(g.means).data_ptr() == t.data_ptr()  # a second read: the same memory


def test_arrays_go_to_torch_without_a_copy(statue, predictor):
    torch = pytest.importorskip("torch")  # Debian's python3-torch: the same LibTorch, side by side
    g = predictor.predict(statue, height=HEIGHT)
    means = g.means
    t = torch.from_dlpack(means)
    assert t.data_ptr() == means.ctypes.data and tuple(t.shape) == means.shape
    rgb = g.render(statue.camera(statue.views[0], height=HEIGHT))
    assert torch.from_dlpack(rgb).data_ptr() == rgb.ctypes.data
    # ... and tensors come in: a reference image as a torch tensor, uint8 or float.
    image = statue.image(statue.views[0])
    as_uint8 = torch.from_numpy(np.round(image * 255).astype(np.uint8))
    a = predictor.predict(statue, height=HEIGHT, reference=as_uint8)
    b = predictor.predict(statue, height=HEIGHT, reference=np.round(image * 255) / 255)
    np.testing.assert_array_equal(a.colors, b.colors)


def test_render_of_a_saved_and_reloaded_prediction(tmp_path, statue, predictor):
    g = predictor.predict(statue, height=HEIGHT)
    camera = statue.camera(statue.views[1], height=HEIGHT)
    rgb, depth = g.render(camera, depth=True)
    assert rgb.shape == (camera.height, camera.width, 3) and depth.shape == (camera.height, camera.width)
    assert 0 <= rgb.min() and rgb.max() <= 1 and depth.max() > 0
    g.save(tmp_path / "g.ply")
    loaded = ii.load_gaussians(tmp_path / "g.ply")
    assert len(loaded) == len(g) and loaded.context == []
    # The file holds the scene's frame (the prediction's arrays are in the network's): loaded, it
    # renders the same from the scene's camera.
    mean, scale = g._g._normalization
    np.testing.assert_allclose(loaded.means, g.means * scale + np.array(mean), rtol=1e-5, atol=1e-5 * scale)
    np.testing.assert_allclose(loaded.render(camera), rgb, atol=2e-3)
    g.save(tmp_path / "n.ply", normalized=True)
    np.testing.assert_allclose(ii.load_gaussians(tmp_path / "n.ply").means, g.means, atol=1e-6)


def test_predict_defaults_are_the_commands():
    defaults = {k: p.default for k, p in inspect.signature(ii.Predictor.predict).parameters.items()}
    assert (defaults["align_depth"], defaults["depth_detail"], defaults["frame_margin"], defaults["region_cover"],
            defaults["fade_floaters"], defaults["measured_surface"], defaults["stereo_depth"],
            defaults["frame_margin_drop_seen"], defaults["frame_margin_outer"], defaults["behind_edges"],
            defaults["region_surface"], defaults["flying_pixels"]) == \
        ("photos", 1.5, 0.125, 0.3, 0.3, 0.95, True, True, 0.25, 0.03125, 0.95, "far")
    # Every geometry flag of the commands is a keyword (the library's one table), and the help says so.
    assert defaults["stereo_planes"] == 24 and defaults["behind_edges_jump"] == 0.1, defaults
    assert "frame_margin (`--frame-margin`, default 0.125)" in ii.Predictor.predict.__doc__
    # The renamed keyword still works: flying_pixels_far=False is flying_pixels="keep".
    assert ii._geometry_texts({"flying_pixels_far": False, "stereo_depth": True, "frame_margin": 0.5}) == \
        {"flying_pixels": "keep", "stereo_depth": "true", "frame_margin": "0.5"}


def test_the_depth_is_scaled_to_the_photos_points_by_default(statue, predictor):
    raw = predictor.predict(statue, height=HEIGHT, align_depth="none")
    g = predictor.predict(statue, height=HEIGHT)
    assert raw.geometry["source"] == "off" and raw.geometry["views"] == []
    assert raw.geometry["frame_margin"]["fraction"] == 0.125
    assert raw.geometry["frame_margin"]["outer_fraction"] == 0.25
    assert raw.geometry["frame_margin"]["outer_stride"] == 2
    dense_only = predictor.predict(statue, height=HEIGHT, frame_margin_outer=0).geometry["frame_margin"]
    assert g.geometry["behind_edges"]["fraction"] == 0.03125 and g.geometry["behind_edges"]["pixels"] == 2
    assert predictor.predict(statue, height=HEIGHT, behind_edges=0).geometry["behind_edges"]["gaussians"] == 0
    assert dense_only["outer_pixels"] == dense_only["pixels"] and \
        dense_only["gaussians"] < g.geometry["frame_margin"]["gaussians"], dense_only
    assert g.geometry["frame_margin"]["dropped"] > 0, g.geometry["frame_margin"]
    whole = predictor.predict(statue, height=HEIGHT, frame_margin_drop_seen=False).geometry["frame_margin"]
    assert whole["dropped"] == 0 and whole["gaussians"] == g.geometry["frame_margin"]["gaussians"] + \
        g.geometry["frame_margin"]["dropped"], whole
    # The statue has no depth maps: its photos measure the surface (none at all without alignment).
    assert raw.geometry["measured_surface"] == {}
    surface = g.geometry["measured_surface"]
    assert surface["source"] == "the photos (stereo)" and surface["views"] == g.context, surface
    assert all(0.05 < known < 1 for known in surface["known"]) and surface["opacity"] == 0.95, surface
    alone = predictor.predict(statue, height=HEIGHT, stereo_depth=False).geometry["measured_surface"]
    assert alone["views"] == [] and alone["source"] == "", alone
    assert g.geometry["source"].startswith("points triangulated from 4 views' photos ("), g.geometry
    assert [v["view"] for v in g.geometry["views"]] == g.context
    assert all(v["points"] >= 20 and v["scale"] > 0 for v in g.geometry["views"]), g.geometry
    assert any(abs(v["scale"] - 1) > 0.5 for v in g.geometry["views"]), g.geometry  # the statue is seen too near
    # The per-pixel rows come first, then the frame margin's, those behind depth edges, the region cover's.
    pixels = len(raw) - sum(raw.geometry[step]["gaussians"] for step in ("frame_margin", "behind_edges", "region_cover"))
    # The alignment keeps the colours; the region surface gives the reference's region (the first
    # view's rows) its photo's.
    np.testing.assert_array_equal(g.colors[pixels // 4:pixels], raw.colors[pixels // 4:pixels])
    kept = predictor.predict(statue, height=HEIGHT, region_surface=0)
    assert kept.geometry["region_surface"]["gaussians"] == 0 < g.geometry["region_surface"]["gaussians"]
    np.testing.assert_array_equal(kept.colors[:pixels], raw.colors[:pixels])
    assert not np.allclose(g.means[:pixels], raw.means[:pixels])
    # Beyond one scale per view the depth follows the points near each pixel (depth_detail).
    assert g.geometry["detail"] == 1.5 and all(v["detail_mean"] > 0 for v in g.geometry["views"]), g.geometry
    scale_only = predictor.predict(statue, height=HEIGHT, depth_detail=0)
    assert scale_only.geometry["detail"] == 0 and all(v["detail_mean"] == 0 for v in scale_only.geometry["views"])
    assert [v["scale"] for v in scale_only.geometry["views"]] == [v["scale"] for v in g.geometry["views"]]
    assert not np.allclose(g.means[:pixels], scale_only.means[:pixels])


def test_bad_arguments_raise_clear_errors(tmp_path, statue, predictor):
    with pytest.raises(ii.Error, match="does-not-exist"):
        ii.load_scene(tmp_path / "does-not-exist")
    with pytest.raises(ii.Error, match="no view named 'nope'"):
        statue.camera("nope")
    with pytest.raises(ii.Error, match="nope"):
        predictor.predict(statue, context=["nope"], height=HEIGHT)
    with pytest.raises(ii.Error, match="--align-depth 'nope': none, depth-maps, photos or any"):
        predictor.predict(statue, height=HEIGHT, align_depth="nope")
    with pytest.raises(ii.Error, match="--frame-margin '2': a number from 0 to 1"):
        predictor.predict(statue, height=HEIGHT, frame_margin=2)
    with pytest.raises(TypeError, match="unexpected keyword argument 'frame_margins' \\(the geometry's: align_depth"):
        predictor.predict(statue, height=HEIGHT, frame_margins=0)
    with pytest.raises(ii.Error, match=r"reference: expected 3 channels, got an array of shape \(4, 4, 1\)"):
        predictor.predict(statue, reference=np.zeros((4, 4, 1), np.float32), height=HEIGHT)
    with pytest.raises(ii.Error, match="unsupported element type"):
        predictor.predict(statue, reference=np.zeros((4, 4, 3), np.int64), height=HEIGHT)
    with pytest.raises(ii.Error, match="c2w: expected 4 rows, got 3"):
        ii.Camera(8, 8, 10, 10, 4, 4, [[1, 0, 0, 0]] * 3)
    with pytest.raises(TypeError):
        predictor.predict("not a scene")
    with pytest.raises(ii.Error, match="were not predicted from a scene"):
        g = predictor.predict(statue, height=HEIGHT)
        g.save(tmp_path / "g.ply")
        ii.load_gaussians(tmp_path / "g.ply").refine(statue, preset="2")
    with pytest.raises(ii.Error, match="unknown.ply"):
        ii.Predictor(tmp_path / "unknown.ply")
    with pytest.raises(ii.Error, match=r"set_threads: -1 is not a thread count \(0: \$OMP_NUM_THREADS, else every core\)"):
        ii.set_threads(-1)
    assert issubclass(ii.Error, RuntimeError)


def test_refine_reports_progress_and_stops_on_the_callbacks_exception(statue, predictor):
    g = predictor.predict(statue, height=HEIGHT)
    seen = []
    refined = g.refine(statue, preset="4", progress=seen.append)
    assert [p["step"] for p in seen] == [1, 2, 3, 4]
    assert all(p["loss"] > 0 for p in seen) and seen[-1]["fraction"] == pytest.approx(1.0)
    assert refined.refine_report["steps"] == 4 and g.refine_report is None
    assert refined.sh_degree == -1 and len(refined) > 0

    def stop(progress):
        raise KeyboardInterrupt("stopped by the user")
    with pytest.raises(KeyboardInterrupt, match="stopped by the user"):
        g.refine(statue, preset="50", progress=stop)


def test_reconstruct_trains_the_whole_capture_and_scores_its_held_out_views(shared, tmp_path):
    from conftest import shared_data
    cup = shared_data(shared, "realtrain") / "custom_coffee_cup"
    scene = ii.load_scene(cup, hold_out_every=8, keep_object=True)
    seen = []
    g = ii.reconstruct(scene, steps=60, height=48, eval=True, sh_degree=1, progress=seen.append)
    report = g.reconstruct_report
    assert [p["step"] for p in seen] == list(range(1, 61))
    assert report["held_out"] == [v for v in scene.test_views]
    assert report["start"]["source"] == "triangulated from the photos" and report["start"]["points"] > 1000
    assert report["scored"] == "held-out views (every 8th)" and len(report["views"]) == len(scene.test_views)
    assert 10 < report["psnr"] < 40 and g.sh_degree == 1 and len(g) == report["splats"]
    # The capture's own frame: the file written is what was trained, and other tools' files line up.
    g.save(tmp_path / "cup.ply")
    np.testing.assert_allclose(ii.load_gaussians(tmp_path / "cup.ply").means, g.means, rtol=0, atol=1e-6)
    # Continued from those Gaussians: 0 steps scores them as they are.
    again = ii.reconstruct(scene, steps=0, height=48, eval=True, sh_degree=1, start=g)
    assert again.reconstruct_report["psnr"] == pytest.approx(report["psnr"], abs=1e-3)
    with pytest.raises(ii.Error, match=r"eval=True scores held-out views: load the scene with hold_out_every=8"):
        ii.reconstruct(ii.load_scene(cup), steps=1, eval=True)


def test_masks_from_one_region(statue, predictor):
    view = statue.views[2]
    region = statue.mask(view)
    # The statue has no COLMAP points: without a predictor there is no depth to lift the region with.
    with pytest.raises(ii.Error, match=f"no depth for view {view}"):
        ii.masks_from_one(statue, view, region)
    masks, report = ii.masks_from_one(statue, view, region, predictor=predictor, height=HEIGHT)
    assert set(masks) == set(statue.views)
    np.testing.assert_array_equal(masks[view], region)
    assert report["depth_source"] == "network" and report["view"] == view
    # The statue's own masks are the answer to compare with: the propagated ones overlap them.
    for other in statue.views[3:6]:
        own, propagated = statue.mask(other) > 0.5, masks[other] > 0.5
        assert (own & propagated).sum() / (own | propagated).sum() > 0.4, other


def test_select_masks_the_clicked_object_in_every_view(tmp_path, statue, predictor):
    view = statue.views[0]
    own = statue.mask(view) > 0.5
    ys, xs = np.nonzero(own)
    click = (float(np.median(xs)), float(np.median(ys)))
    masks, report = ii.select(statue, view, click, predictor=predictor, height=128)
    assert set(masks) == set(statue.views)
    assert report["clicks"] == [list(click)] and 0 < report["selected_points"] < report["points"]
    # The marked view's mask holds mostly the statue (the drape the click is on).
    mine = masks[view] > 0.5
    assert (mine & own).sum() / mine.sum() > 0.7
    with pytest.raises(ii.Error, match=f"the click \\(-5, 3\\) is outside view {view}'s image"):
        ii.select(statue, view, (-5, 3), predictor=predictor, height=128)
    with pytest.raises(ValueError, match="is not a point"):
        ii.select(statue, view, [(1, 2, 3)], predictor=predictor, height=128)
    # The splats of a splat scene: the same click on its camera.
    predictor.predict(statue, height=HEIGHT).save(tmp_path / "scene.ply")
    scene = ii.load_gaussians(tmp_path / "scene.ply")
    chosen = scene.select(statue.camera(view), click, view=view)
    assert chosen.dtype == bool and chosen.shape == (len(scene),) and 0 < chosen.sum() < len(scene)
    part = scene.subset(chosen)
    assert len(part) == chosen.sum() and np.array_equal(part.means, scene.means[chosen])
    with pytest.raises(ii.Error, match="subset: expected a bool array of"):
        scene.subset(chosen[:-1])
    filled = scene.fill(view=view, click=click, scene=statue, views=2, height=HEIGHT, predictor=predictor)
    assert filled.fill_report["splats"]["removed"] == chosen.sum()
    with pytest.raises(ii.Error, match="click= is on a view: name it with view="):
        scene.fill(click=click, scene=statue, predictor=predictor)


def test_a_segmenter_outlines_the_click_as_the_reference_code_does(tmp_path, statue, predictor):
    # The small MobileSAM-layout fixture of tests/segment (seeded random weights) and the mask the
    # reference code gave for this click on this photo (scripts/segmenter-reference).
    fixture = REPO / "tests" / "segment" / "fixture"
    segmenter = ii.Segmenter(fixture / "mobile_sam_small.pt", precision="fp32")
    assert segmenter.description.startswith("MobileSAM TinyViT") and segmenter.precision == "fp32"
    photo = statue.image("IMG_2707")
    mask, report = segmenter.segment(photo, (301.5, 259.5))
    reference = np.load(fixture / "statue_IMG_2707_click.npz")["mask"]
    assert mask.shape == reference.shape and ((mask > 0.5) != reference).sum() <= 5
    assert len(report["scores"]) == 3 and report["chosen"] == int(np.argmax(report["scores"]))
    # select() with it: the clicked view's mask is the segmenter's, lifted to every view.
    masks, how = ii.select(statue, "IMG_2707", (301.5, 259.5), segmenter=segmenter, predictor=predictor, height=128)
    assert how["clicked_mask"] == "segmenter" and set(masks) == set(statue.views)
    assert ((masks["IMG_2707"] > 0.5) != reference).sum() <= 5
    with pytest.raises(ii.Error, match="not_click= needs segmenter="):
        ii.select(statue, "IMG_2707", (301.5, 259.5), not_click=(3, 3), predictor=predictor, height=128)
    with pytest.raises(ii.Error, match="no such segmentation model file"):
        ii.Segmenter(tmp_path / "absent.pt")


def test_select_takes_a_box_without_a_segmenter(statue, predictor):
    # IMG_2707's label's box grown by 5 %: GrabCut in it, as `masks --box` does.
    box = (217.4, 122.7, 369.6, 346.3)
    masks, report = ii.select(statue, "IMG_2707", box=box, segmenter=None, predictor=predictor, height=128)
    assert report["clicked_mask"] == "GrabCut in the box" and report["box"] == list(box)
    own = statue.mask("IMG_2707") > 0.5
    mine = masks["IMG_2707"] > 0.5
    assert (mine & own).sum() / own.sum() > 0.9 and (mine & own).sum() / mine.sum() > 0.95
    with pytest.raises(ii.Error, match="the box 0,0,504,378 covers the whole photo"):
        ii.select(statue, "IMG_2707", box=(0, 0, 504, 378), segmenter=None, predictor=predictor, height=128)
    with pytest.raises(ValueError, match="give click=.* or box="):
        ii.select(statue, "IMG_2707", segmenter=None, predictor=predictor)


def test_evaluate_writes_what_the_cli_writes(tmp_path, cli, statue_dir):
    args = ["--hold-out-every", "8", "--height", str(HEIGHT), "--device", "cpu", "--no-report", "--threads", "1"]
    subprocess.run([str(cli), "eval", "--scene", str(statue_dir), "--out", str(tmp_path / "cli"), *args],
                   check=True, capture_output=True)
    ii.set_threads(1)  # one thread on both sides, as in the prediction's test above
    try:
        m = ii.evaluate(statue_dir, tmp_path / "py", hold_out_every=8, height=HEIGHT, device="cpu", report=False)
    finally:
        ii.set_threads(0)
    cli_m = json.loads((tmp_path / "cli" / "metrics.json").read_text())
    assert m["mean"] == cli_m["mean"]
    assert sorted(os.listdir(tmp_path / "py" / "renders")) == sorted(os.listdir(tmp_path / "cli" / "renders"))
    for name in os.listdir(tmp_path / "py" / "renders"):
        assert (tmp_path / "py" / "renders" / name).read_bytes() == (tmp_path / "cli" / "renders" / name).read_bytes()


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


def test_no_leak_over_100_predictions(statue, predictor):
    def predict_and_read():
        g = predictor.predict(statue, height=HEIGHT)
        return float(g.means.sum() + g.render(statue.camera(statue.views[0], height=32)).sum())

    for _ in range(10):
        predict_and_read()
    gc.collect()
    before = rss_mb()
    for _ in range(100):
        predict_and_read()
    gc.collect()
    grown = rss_mb() - before
    # One prediction's Gaussians are ~3 MB here: 100 kept would be hundreds of MB.
    assert grown < 40, f"RSS grew by {grown:.0f} MB over 100 predictions"


def test_long_calls_release_the_gil(statue, predictor):
    ticks = 0
    done = threading.Event()

    def count():
        nonlocal ticks
        while not done.is_set():
            ticks += 1
    counter = threading.Thread(target=count)
    counter.start()
    try:
        before = ticks
        predictor.predict(statue, height=128)
        during = ticks - before
    finally:
        done.set()
        counter.join()
    assert during > 1000, f"the counting thread ran {during} times during the prediction"


def test_log_level_quiets_the_library(capfd, statue, predictor):
    try:
        ii.set_log_level("warning")
        predictor.predict(statue, height=HEIGHT)
        assert "classical 'ns' method" in capfd.readouterr().out  # predict warns that no reference was given
        ii.set_log_level("error")
        predictor.predict(statue, height=HEIGHT)
        assert capfd.readouterr().out == ""
        with pytest.raises(ii.Error, match="'loud' is not one of trace, debug, info"):
            ii.set_log_level("loud")
    finally:
        ii.set_log_level("info")


def test_help_reads_well():
    assert "one forward pass" in ii.Predictor.predict.__doc__
    assert "LaMa" in ii.Predictor.predict.__doc__
    assert ii.load_scene.__doc__.startswith("Reads a scene folder")
    assert "from_dlpack" in ii.__doc__
    stub = pathlib.Path(ii._core.__file__).with_name("_core.pyi")
    assert stub.is_file() and "class Predictor" in stub.read_text()


def test_the_example_removes_the_statue_and_writes_a_video(tmp_path, statue_dir):
    example = pathlib.Path(__file__).resolve().parents[2] / "examples" / "remove_object.py"
    subprocess.run([sys.executable, str(example), str(statue_dir), str(tmp_path), "--height", str(HEIGHT),
                    "--refine", "3", "--frames", "6"], check=True, capture_output=True)
    assert (tmp_path / "gaussians.spz").stat().st_size > 1000
    video = tmp_path / "orbit.mp4"
    assert video.stat().st_size > 1000
    probe = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
                            "stream=nb_read_frames", "-of", "csv=p=0", str(video)], capture_output=True, text=True,
                           check=True)
    assert int(probe.stdout.strip()) == 6


def test_a_wheel_builds(tmp_path):
    # In the build folder the installed package came from (its libraries are built already).
    repo = pathlib.Path(__file__).resolve().parents[2]
    build = os.environ.get("INSTAINPAINT_BUILD_DIR", str(repo / "build"))
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--disable-pip-version-check",
                    "--no-build-isolation", "--no-deps", f"--config-settings=build-dir={build}", "-w", str(tmp_path), str(repo)],
                   check=True, capture_output=True)
    wheels = list(tmp_path.glob("instainpaint-0.1.0-*.whl"))
    assert len(wheels) == 1
    names = zipfile.ZipFile(wheels[0]).namelist()
    assert "instainpaint/__init__.py" in names and "instainpaint/py.typed" in names
    assert any(n.startswith("instainpaint/_core") and n.endswith(".so") for n in names)


def test_fill_removes_a_box_and_fills_it_keeping_every_other_splat(tmp_path, statue, predictor):
    predictor.predict(statue, height=HEIGHT).save(tmp_path / "scene.ply")  # the scene's frame
    scene = ii.load_gaussians(tmp_path / "scene.ply")
    means = scene.means.astype(np.float64)
    centre = np.median(means, axis=0)
    size = np.percentile(means, 70, axis=0) - np.percentile(means, 30, axis=0)
    inside = np.all(np.abs(means - centre) <= size / 2, axis=1)
    filled = scene.fill(box=[*centre, *size], scene=statue, views=2, height=HEIGHT, predictor=predictor)
    report = filled.fill_report
    assert report["splats"]["removed"] == inside.sum() > 0
    assert report["splats"]["added"] > 0
    assert len(filled) == len(scene) - inside.sum() + report["splats"]["added"]
    kept = int((~inside).sum())
    np.testing.assert_array_equal(filled.means[:kept], scene.means[~inside])  # bit for bit, in order
    new = filled.means[kept:].astype(np.float64)
    spread = np.linalg.norm(means - centre, axis=1)
    assert np.median(np.linalg.norm(new - centre, axis=1)) < np.median(spread)  # where the box was
    assert report["cameras"]["how"].startswith("given")
    assert report["placement"] == "surface"
    assert report["inpainter"] == "ns"
    patched = scene.fill(box=[*centre, *size], scene=statue, views=2, height=HEIGHT, inpainter="patch",
                         predictor=predictor)
    assert patched.fill_report["inpainter"] == "patch"
    np.testing.assert_array_equal(patched.means[:kept], scene.means[~inside])
    with pytest.raises(ii.Error, match="inpainter 'lama': neither telea, ns, patch nor a LaMa file"):
        scene.fill(box=[*centre, *size], scene=statue, inpainter="lama", predictor=predictor)
    # LaMa (the small fixture of tests/inpaint in place of big-lama's weights) paints the hole.
    lama = REPO / "tests" / "inpaint" / "fixture" / "lama-small" / "models" / "best.ckpt"
    painted = scene.fill(box=[*centre, *size], scene=statue, views=2, height=HEIGHT, inpainter=lama,
                         predictor=predictor)
    assert painted.fill_report["inpainter"] == "lama"
    assert painted.fill_report["inpainter_file"]["network"] == "LaMa FFC-ResNet (ngf 8, 2 blocks)"
    network = scene.fill(box=[*centre, *size], scene=statue, views=2, height=HEIGHT, placement="network",
                         predictor=predictor)
    assert network.fill_report["placement"] == "network"
    with pytest.raises(ii.Error, match="fill placement 'nope': surface or network"):
        scene.fill(box=[*centre, *size], scene=statue, placement="nope", predictor=predictor)
    with pytest.raises(ii.Error, match="holds no splat of the Gaussians: its splats lie within"):
        scene.fill(box=[*(centre + 1e6), 1, 1, 1], scene=statue, predictor=predictor)


def test_models_name_the_catalogue_and_say_how_to_bring_a_network(tmp_path):
    import hashlib
    import instainpaint as ii
    listed = ii.models.list()
    assert [n["name"] for n in listed["networks"]] == ["instainpaint", "mobile-sam", "sam-vit-b", "sam-vit-l",
                                                        "sam-vit-h", "big-lama", "big-lama-authors"]
    assert listed["folder"] == os.environ["INSTAINPAINT_MODELS_DIR"]
    assert listed["auto"] == {"checkpoint": None, "segmenter": None, "inpainter": None}
    with pytest.raises(ii.Error, match="mobile-sam: not in the cache; bring it with: instainpaint models get mobile-sam"):
        ii.models.path("mobile-sam")
    with pytest.raises(ii.Error, match=r"ii.models.get\("):
        ii.Segmenter()
    # Without a network in the cache, "auto" takes the built-in path.
    assert ii.Predictor(device="cpu").model == "<embedded default model>"
    # A file that is not the published one is refused with both checksums, and nothing is kept.
    fixture = REPO / "tests" / "segment" / "fixture" / "mobile_sam_small.pt"
    with pytest.raises(ii.Error) as refused:
        ii.models.import_file(fixture, "mobile-sam")
    assert hashlib.md5(fixture.read_bytes()).hexdigest() in str(refused.value)
    assert "f3c0d8cda613564d499310dab6c812cd" in str(refused.value)
    assert not ii.models.remove("mobile-sam")
