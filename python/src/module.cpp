// The Python module `instainpaint._core`: a thin layer over the library, like the CLI. Python's
// own conveniences (docstrings of the package, dicts from JSON, path handling) live in
// python/instainpaint/__init__.py; everything here is a call into the library.
//
// Arrays: attributes, renders and depth leave as NumPy arrays over the library's own memory
// (no copy; they keep it alive), which any DLPack consumer (torch.from_dlpack, jax, cupy)
// takes without a copy either; on a GPU they leave as DLPack-capable arrays on the device.
// Arrays in (images, masks) may be anything with the buffer protocol or DLPack, float in [0, 1]
// or uint8; they are copied into the library's images.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/function.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <memory>

#include <spdlog/spdlog.h>

#include "models/download.h"
#include "inpaint/lama_inpainter.h"
#include "common/error.h"
#include "common/files.h"
#include "data/inpaint2d.h"
#include "data/scene_cameras.h"
#include "io/video.h"
#include "render/frames.h"
#include "common/torch.h"
#include "edit/scene_masks.h"
#include "eval/protocol.h"
#include "fill/fill.h"
#include "fill/region.h"
#include "geometry/settings.h"
#include "io/image.h"
#include "io/splat_file.h"
#include "model/device.h"
#include "predict/predictor.h"
#include "refine/reconstruct.h"
#include "refine/refine.h"
#include "segment/segmenter.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace nb = nanobind;
using namespace nb::literals;

namespace ii::python {
namespace {

// ---- arrays --------------------------------------------------------------------------------

// A float32 tensor as an array sharing its memory; the capsule keeps the tensor alive.
nb::object array_of(torch::Tensor t) {
  t = t.contiguous();
  if (t.scalar_type() != torch::kFloat) t = t.to(torch::kFloat);
  auto* kept = new torch::Tensor(t);
  nb::capsule owner(kept, [](void* p) noexcept { delete static_cast<torch::Tensor*>(p); });
  std::vector<size_t> shape(t.sizes().begin(), t.sizes().end());
  if (t.is_cuda()) {
    return nb::cast(nb::ndarray<float>(t.data_ptr<float>(), shape.size(), shape.data(), owner, nullptr,
                                       nb::dtype<float>(), nb::device::cuda::value, t.get_device()));
  }
  return nb::cast(nb::ndarray<nb::numpy, float>(t.data_ptr<float>(), shape.size(), shape.data(), owner));
}

using AnyArray = nb::ndarray<nb::ro, nb::device::cpu>;

// A segmenter shared by the Python object and the requests that use it.
struct PySegmenter {
  std::shared_ptr<const Segmenter> segmenter;
};

std::vector<Click> clicks_of(const std::vector<std::pair<double, double>>& points) {
  std::vector<Click> out;
  for (const auto& [x, y] : points) out.push_back({x, y});
  return out;
}

// An image from an H x W (x C) array: float in [0, 1] (any float type) or uint8 in [0, 255].
Image image_of(const AnyArray& a, const char* what, int channels) {
  if (a.ndim() != 2 && a.ndim() != 3) fail("{}: expected an H x W{} array, got {} dimensions", what,
                                           channels == 1 ? "" : " x 3", a.ndim());
  const int h = static_cast<int>(a.shape(0)), w = static_cast<int>(a.shape(1));
  const int c = a.ndim() == 3 ? static_cast<int>(a.shape(2)) : 1;
  if (c != channels) fail("{}: expected {} channel{}, got an array of shape ({}, {}, {})", what, channels,
                          channels == 1 ? "" : "s", h, w, c);
  if (h == 0 || w == 0) fail("{}: the array is empty", what);
  // As a tensor over the caller's memory (strides honoured), then one copy into the image.
  std::vector<int64_t> shape{h, w, c}, strides{a.stride(0), a.stride(1), a.ndim() == 3 ? a.stride(2) : 1};
  torch::ScalarType type;
  if (a.dtype() == nb::dtype<uint8_t>()) type = torch::kByte;
  else if (a.dtype() == nb::dtype<float>()) type = torch::kFloat;
  else if (a.dtype() == nb::dtype<double>()) type = torch::kDouble;
  else if (a.dtype() == nb::dtype<bool>()) type = torch::kBool;
  else fail("{}: unsupported element type (use float32, float64, uint8 or bool)", what);
  torch::Tensor t = torch::from_blob(const_cast<void*>(a.data()), shape, strides, torch::TensorOptions(type));
  return image_from_hwc(type == torch::kByte ? t.to(torch::kFloat) / 255.0 : t);
}

nb::object array_of(const Image& image) {
  torch::Tensor t = torch::from_blob(const_cast<float*>(image.pixels.data()), {image.height, image.width, image.channels},
                                     torch::kFloat)
                        .clone();
  if (image.channels == 1) t = t.squeeze(2);
  return array_of(t);
}

// ---- cameras -------------------------------------------------------------------------------

Eigen::Matrix4d matrix_of(const std::vector<std::vector<double>>& rows) {
  if (rows.size() != 4) fail("c2w: expected 4 rows, got {}", rows.size());
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    if (rows[r].size() != 4) fail("c2w: row {} has {} numbers, expected 4", r, rows[r].size());
    for (int c = 0; c < 4; ++c) m(r, c) = rows[r][c];
  }
  return m;
}

std::vector<std::vector<double>> rows_of(const Eigen::Matrix4d& m) {
  std::vector<std::vector<double>> rows(4, std::vector<double>(4));
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) rows[r][c] = m(r, c);
  return rows;
}

const View& view_of(const Scene& scene, const std::string& name) {
  const View* v = scene.find(name);
  if (!v) fail("{}: no view named '{}'", scene.root.string(), name);
  return *v;
}

// ---- what Python holds ---------------------------------------------------------------------

// Gaussians with what they came from: the frame they live in (the prediction's pose
// normalisation), and for a prediction what refinement needs (the prediction and its input).
struct PyGaussians {
  GaussianSet set;
  PoseNormalization normalization;
  std::shared_ptr<const Prediction> prediction;
  std::shared_ptr<const SceneInputOptions> input;
  std::string refine_report;  // JSON of the refinement that made these, if one did
  std::string fill_report;    // JSON of the fill that made these, if one did
  std::string reconstruct_report;  // JSON of the reconstruction that made these, if one did
};

// A splat file's values of Gaussians, in the scene's frame.
SplatCloud scene_splats(const PyGaussians& g) {
  return splats_from_gaussians(in_scene_frame(g.set, g.normalization).to(torch::kCPU));
}

// An image given as a file name or an array.
Image image_or_file(const nb::object& value, const char* what, int channels) {
  if (nb::isinstance<nb::str>(value) || nb::hasattr(value, "__fspath__")) {
    const std::string path = nb::cast<std::string>(nb::str(value));
    return channels == 1 ? read_mask(path) : read_image_rgb(path);
  }
  return image_of(nb::cast<AnyArray>(value), what, channels);
}

SceneInputOptions input_options(const std::vector<std::string>& context, int views, const nb::object& reference,
                                const std::string& reference_view, int height, bool keep_object,
                                const std::map<std::string, AnyArray>& masks) {
  SceneInputOptions o;
  o.context = context;
  o.num_views = views;
  o.reference_view = reference_view;
  o.preprocess.height = height;
  o.keep_object = keep_object;
  if (!reference.is_none()) {
    if (nb::isinstance<nb::str>(reference) || nb::hasattr(reference, "__fspath__"))
      o.reference = std::filesystem::path(nb::cast<std::string>(nb::str(reference)));
    else
      o.reference_image = image_of(nb::cast<AnyArray>(reference), "reference", 3);
  }
  for (const auto& [name, mask] : masks) o.masks[name] = image_of(mask, ("mask of " + name).c_str(), 1);
  return o;
}

// set_threads' count (0: the default plan), kept for every later runtime set-up: a Predictor made
// after set_threads keeps the caller's count, as `--threads` does for a command.
int requested_threads = 0;
bool runtime_on_gpu = false;

Runtime python_runtime(const std::string& device, const std::string& precision) {
  const Runtime r = set_up_runtime(device, requested_threads, precision);
  runtime_on_gpu = r.device.is_cuda();
  return r;
}

}  // namespace

NB_MODULE(_core, m) {
  m.doc() = "instainpaint's library (see the package `instainpaint` for documentation).";
  nb::exception<Error>(m, "Error", PyExc_RuntimeError);

  m.def("set_log_level",
        [](const std::string& level) {
          const auto parsed = spdlog::level::from_str(level);
          // from_str answers "off" for any name it does not know
          if (parsed == spdlog::level::off && level != "off")
            fail("set_log_level: '{}' is not one of trace, debug, info, warning, error, critical, off", level);
          spdlog::set_level(parsed);
        },
        "level"_a,
        "How much the library prints to standard output: trace, debug, info (default), warning, error, "
        "critical or off.");

  // predict()'s geometry keywords: geometry/settings.h's table (the commands' flags), each as
  // (keyword, kind, default as text, choices, help), read here rather than written twice.
  {
    const GeometryOptions defaults;
    nb::list settings;
    for (const GeometrySetting& g : geometry_settings()) {
      std::string keyword = g.name;
      std::replace(keyword.begin(), keyword.end(), '-', '_');
      settings.append(nb::make_tuple(keyword, g.kind, g.get(defaults), g.choices, g.help));
    }
    m.attr("_geometry_settings") = settings;
  }

  // ii.models: the catalogue and the cache (instainpaint models).
  m.def("_models_get",
        [](const std::string& name, const std::string& mirror, double timeout_s, bool progress) {
          const ModelEntry& entry = catalogue_entry(name);
          if (const auto m = cached_model(entry)) return m->file.string();
          DownloadOptions o;
          o.mirror = mirror;
          o.timeout_s = timeout_s;
          o.progress = progress;
          nb::gil_scoped_release release;
          return download_model(entry, o).file.string();
        },
        "name"_a, "mirror"_a, "timeout"_a, "progress"_a);
  m.def("_models_path", [](const std::string& name) { return verified_model_path(name).string(); }, "name"_a);
  m.def("_models_list", [] { return catalogue_state().dump(); });
  m.def("_models_import",
        [](const std::string& file, const std::string& name) {
          return import_model(catalogue_entry(name), file).file.string();
        },
        "file"_a, "name"_a);
  m.def("_models_remove", [](const std::string& name) { return remove_cached(catalogue_entry(name)); }, "name"_a);

  m.def("set_threads",
        [](int threads) {
          if (threads < 0) fail("set_threads: {} is not a thread count (0: $OMP_NUM_THREADS, else every core)", threads);
          requested_threads = threads;
          set_cpu_threads(threads, runtime_on_gpu);
        },
        "threads"_a,
        "The CPU threads of the library's work, as the CLI's --threads: 0 (default) uses $OMP_NUM_THREADS, "
        "else every core. It holds for every later Predictor and evaluate.");

  nb::class_<Camera>(m, "Camera")
      .def("__init__",
           [](Camera* c, int width, int height, double fx, double fy, double cx, double cy,
              const std::vector<std::vector<double>>& c2w) {
             new (c) Camera();
             if (width <= 0 || height <= 0) fail("Camera: width and height must be positive, got {}x{}", width, height);
             c->K = Intrinsics{width, height, fx, fy, cx, cy};
             c->c2w = matrix_of(c2w);
           },
           "width"_a, "height"_a, "fx"_a, "fy"_a, "cx"_a, "cy"_a, "c2w"_a)
      .def_prop_ro("width", [](const Camera& c) { return c.K.width; })
      .def_prop_ro("height", [](const Camera& c) { return c.K.height; })
      .def_prop_ro("fx", [](const Camera& c) { return c.K.fx; })
      .def_prop_ro("fy", [](const Camera& c) { return c.K.fy; })
      .def_prop_ro("cx", [](const Camera& c) { return c.K.cx; })
      .def_prop_ro("cy", [](const Camera& c) { return c.K.cy; })
      .def_prop_ro("c2w", [](const Camera& c) { return rows_of(c.c2w); })
      .def("resized", &Camera::resized, "width"_a, "height"_a)
      .def("__repr__", [](const Camera& c) {
        return fmt::format("Camera({}x{}, fx={:.1f}, centre=({:.3f}, {:.3f}, {:.3f}))", c.K.width, c.K.height, c.K.fx,
                           c.center().x(), c.center().y(), c.center().z());
      });

  nb::class_<Scene>(m, "Scene")
      .def_prop_ro("root", [](const Scene& s) { return s.root.string(); })
      .def_prop_ro("format", [](const Scene& s) { return s.format; })
      .def_prop_ro("views", [](const Scene& s) {
        std::vector<std::string> names;
        for (const View& v : s.views) names.push_back(v.name);
        return names;
      })
      .def_prop_ro("test_views", [](const Scene& s) {
        std::vector<std::string> names;
        for (const View& v : s.test_views) names.push_back(v.name);
        return names;
      })
      .def_prop_ro("warnings", [](const Scene& s) { return s.warnings; })
      .def("camera",
           [](const Scene& s, const std::string& name, std::optional<int> height) {
             Camera c = view_of(s, name).camera;
             if (height) {
               if (*height <= 0) fail("camera: height must be positive, got {}", *height);
               const int width = static_cast<int>(std::lround(static_cast<double>(c.K.width) * *height / c.K.height));
               c = c.resized(width, *height);
             }
             return c;
           },
           "view"_a, "height"_a.none() = nb::none(),
           "The camera of a view (input or test), at its photo's size or scaled to `height` rows.")
      .def("image", [](const Scene& s, const std::string& name) { return array_of(load_view_image(view_of(s, name))); },
           "view"_a, "The view's photo as an H x W x 3 float32 array in [0, 1].")
      .def("mask",
           [](const Scene& s, const std::string& name) -> nb::object {
             const std::optional<Image> mask = load_view_mask(view_of(s, name));
             return mask ? array_of(*mask) : nb::none();
           },
           "view"_a, "The view's object mask (H x W float32, 1 = object), or None.")
      .def("__repr__", [](const Scene& s) {
        return fmt::format("Scene('{}', format='{}', {} views, {} test views)", s.root.string(), s.format,
                           s.views.size(), s.test_views.size());
      })
      .def("__len__", [](const Scene& s) { return s.views.size(); });

  m.def("_load_scene",
        [](const std::string& path, const std::string& format, const std::string& images,
           const std::optional<std::string>& masks, int hold_out_every, bool keep_object) {
          SceneOptions o;
          o.format = format;
          o.image_folder = images;
          if (masks) o.mask_dir = *masks;
          o.hold_out_every = hold_out_every;
          o.hold_out_whole = keep_object;
          nb::gil_scoped_release release;
          return load_scene(path, o);
        },
        "path"_a, "format"_a, "images"_a, "masks"_a.none(), "hold_out_every"_a, "keep_object"_a);

  nb::class_<PyGaussians>(m, "Gaussians")
      .def("__len__", [](const PyGaussians& g) { return g.set.size(); })
      .def_prop_ro("means", [](const PyGaussians& g) { return array_of(g.set.means); })
      .def_prop_ro("quats", [](const PyGaussians& g) { return array_of(g.set.quats); })
      .def_prop_ro("scales", [](const PyGaussians& g) { return array_of(g.set.scales); })
      .def_prop_ro("opacities", [](const PyGaussians& g) { return array_of(g.set.opacities.reshape({-1})); })
      .def_prop_ro("colors", [](const PyGaussians& g) { return array_of(g.set.colors); })
      .def_prop_ro("sh_degree", [](const PyGaussians& g) { return g.set.sh_degree; })
      .def_prop_ro("device", [](const PyGaussians& g) { return g.set.means.device().str(); })
      .def_prop_ro("_normalization", [](const PyGaussians& g) {
        const auto& n = g.normalization;
        return std::make_pair(std::vector<double>{n.mean.x(), n.mean.y(), n.mean.z()}, n.scale);
      })
      .def_prop_ro("_refine_report", [](const PyGaussians& g) { return g.refine_report; })
      .def_prop_ro("_reconstruct_report", [](const PyGaussians& g) { return g.reconstruct_report; })
      .def_prop_ro("_geometry", [](const PyGaussians& g) {
        return g.prediction ? g.prediction->describe_geometry().dump() : std::string();
      })
      .def_prop_ro("_fill_report", [](const PyGaussians& g) { return g.fill_report; })
      .def_prop_ro("context", [](const PyGaussians& g) {
        std::vector<std::string> names;  // the views the network saw, reference first
        if (g.prediction)
          for (const PreparedView& v : g.prediction->input.views) names.push_back(v.name);
        return names;
      })
      .def("save", [](const PyGaussians& g, const std::string& path, bool normalized) {
        nb::gil_scoped_release release;
        const GaussianSet set = normalized ? g.set : in_scene_frame(g.set, g.normalization);
        write_splats(path, splats_from_gaussians(set.to(torch::kCPU)));
      }, "path"_a, "normalized"_a)
      .def("_subset",
           [](const PyGaussians& g, const AnyArray& keep) {
             if (keep.ndim() != 1 || keep.shape(0) != static_cast<size_t>(g.set.size()) || keep.dtype() != nb::dtype<bool>())
               fail("subset: expected a bool array of {} values, one per Gaussian", g.set.size());
             const torch::Tensor take =
                 torch::from_blob(const_cast<void*>(keep.data()), {static_cast<int64_t>(keep.shape(0))},
                                  {static_cast<int64_t>(keep.stride(0))}, torch::kBool)
                     .clone();
             PyGaussians out;
             out.normalization = g.normalization;
             out.set = select_rows(g.set, take.to(g.set.means.device()));
             return out;
           },
           "keep"_a)
      .def("_render",
           [](const PyGaussians& g, const Camera& camera, std::array<float, 3> background) {
             RenderCamera rc;
             rc.camera = g.normalization.apply(camera);
             RenderOptions ro;
             ro.background = background;
             RenderOutput out;
             {
               nb::gil_scoped_release release;
               torch::NoGradGuard no_grad;
               out = render(g.set, rc, ro);
             }
             return std::make_pair(array_of(out.rgb), array_of(out.depth.squeeze(2)));
           },
           "camera"_a, "background"_a)
      .def("_render_video",
           [](const PyGaussians& g, const Scene& scene, const std::string& path, const std::string& trajectory,
              int frames, int height, int fps, const std::function<void(int, int)>& progress) {
             if (frames < 2 || height < 8 || fps < 1) fail("render_video: needs frames >= 2, height >= 8, fps >= 1");
             if (!ffmpeg_available()) fail("render_video: ffmpeg is not installed (scripts/install-deps.sh installs it)");
             SceneCameraOptions o;
             o.normalize = true;  // the frame of a prediction (and of infer's splat files)
             o.trajectory = trajectory == "views" ? "" : trajectory;
             o.frames = frames;
             o.height = height;
             o.width = trajectory == "orbit" ? height : 0;
             nb::gil_scoped_release release;  // a Python callback takes the GIL back (nanobind's wrapper)
             std::vector<NamedCamera> cameras = scene_cameras(scene, o);
             if (trajectory == "views")  // the views' own cameras at `height` rows
               for (NamedCamera& c : cameras)
                 c.camera = c.camera.resized(static_cast<int>(std::lround(double(c.camera.K.width) * height / c.camera.K.height)), height);
             const TemporaryFolder frames_dir("instainpaint-video");
             render_frames(g.set, cameras, {}, {frames_dir.path(), {}, {}}, progress);
             if (!encode_video(frames_dir.path(), path, fps)) fail("render_video: ffmpeg failed to write {}", path);
           },
           "scene"_a, "path"_a, "trajectory"_a, "frames"_a, "height"_a, "fps"_a, "progress"_a.none())
      .def("_refine",
           [](const PyGaussians& g, const Scene& scene, const std::string& setting, int sh_degree,
              std::optional<double> position_rate, bool exposure,
              const std::function<void(int, double, double, double, int64_t)>& progress) {
             if (!g.prediction) fail("refine: these Gaussians were not predicted from a scene (loaded from a file?)");
             RefineOptions o = refine_setting(setting);
             o.sh_degree = sh_degree;
             o.exposure = exposure;
             if (position_rate) o.position_lr = *position_rate * kGaussianSplattingPositionLr;
             // nanobind's wrapper of a Python callable takes the GIL to call, copy or drop it.
             if (progress)
               o.progress = [progress](const RefineProgress& p) {
                 progress(p.step, p.fraction, p.loss, p.eta_s, p.gaussians);
               };
             PyGaussians out;
             nlohmann::json report;
             {
               nb::gil_scoped_release release;
               out.set = refine_prediction(scene, *g.prediction, *g.input, g.set, o, report);
             }
             out.normalization = g.normalization;
             out.prediction = g.prediction;
             out.input = g.input;
             out.refine_report = report.dump();
             return out;
           },
           "scene"_a, "setting"_a, "sh_degree"_a, "position_rate"_a.none(), "exposure"_a, "progress"_a.none());

  m.def("_fill",
        [](const PyGaussians& g, const std::optional<std::vector<double>>& box, const PyGaussians* selection,
           const std::string& view, const nb::object& mask, const std::vector<std::pair<double, double>>& clicks,
           const std::map<std::string, Camera>& cameras, const nb::object& reference,
           const std::string& reference_view, int views, int height,
           const std::optional<std::vector<double>>& up, const std::string& refine, bool all_views,
           const std::string& placement, const std::string& inpainter, const Predictor& predictor) {
          FillOptions o;
          o.placement = parse_fill_placement(placement);
          o.inpainter = inpainter_from_flag(inpainter, "ns");
          o.scene_name = "the Gaussians";
          if (box) {
            std::string text;
            for (double v : *box) text += (text.empty() ? "" : ",") + fmt::format("{}", v);
            // With view=, four numbers are a box on that camera's picture; else a box in the scene's frame.
            if (!view.empty())
              o.view_box = parse_view_box(text, "box=");
            else
              o.box = parse_box(text);
          }
          if (selection) {
            o.selection = scene_splats(*selection);
            o.selection_name = "the selection";
          }
          for (const auto& [name, camera] : cameras) o.cameras.push_back({name, camera});
          if (!view.empty()) {
            o.stroke_view = view;
            for (const auto& [x, y] : clicks) o.clicks.push_back({x, y});
            if (!mask.is_none() && (!o.clicks.empty() || o.view_box))
              fail("fill: view= takes mask= (the stroke drawn on that view), or click= and box= (a point on the object, a box around it)");
            if (mask.is_none() && o.clicks.empty() && !o.view_box)
              fail("fill: view= needs mask= (the stroke drawn on that view), click= (a point on the object) or box= (a box around it)");
            if (!mask.is_none()) o.stroke = image_or_file(mask, "mask", 1);
          } else if (!clicks.empty()) {
            fail("fill: click= is on a view: name it with view=");
          }
          if (!reference.is_none()) o.reference_image = image_or_file(reference, "reference", 3);
          o.camera_options.reference = reference_view;
          o.camera_options.views = views;
          o.camera_options.height = height;
          if (up) {
            if (up->size() != 3) fail("fill: up= takes 3 numbers, got {}", up->size());
            o.camera_options.up = {(*up)[0], (*up)[1], (*up)[2]};
          }
          o.reference_only = !all_views;
          const RefineOptions r = refine_setting(refine.empty() ? "0" : refine);
          if (refine_requested(r)) o.refine = r;
          PyGaussians out;
          {
            nb::gil_scoped_release release;
            const FillResult result = fill_splats(scene_splats(g), o, predictor);
            out.set = gaussians_from_splats(result.splats);
            out.fill_report = result.report().dump();
          }
          return out;
        },
        "gaussians"_a, "box"_a.none(), "selection"_a.none(), "view"_a, "mask"_a.none(), "clicks"_a, "cameras"_a,
        "reference"_a.none(), "reference_view"_a, "views"_a, "height"_a, "up"_a.none(), "refine"_a,
        "all_views"_a, "placement"_a, "inpainter"_a, "predictor"_a);

  m.def("_select_splats",
        [](const PyGaussians& g, const Camera& camera, const std::string& view,
           const std::vector<std::pair<double, double>>& clicks, const std::vector<std::pair<double, double>>& not_clicks,
           const PySegmenter* segmenter) {
          nb::gil_scoped_release release;
          if (segmenter)
            return region_from_segmented_clicks(scene_splats(g), camera, view, clicks_of(clicks), clicks_of(not_clicks),
                                                *segmenter->segmenter);
          if (!not_clicks.empty()) fail("not_click= needs segmenter=: the colour growth takes no such points");
          return region_from_clicks(scene_splats(g), camera, view, clicks_of(clicks));
        },
        "gaussians"_a, "camera"_a, "view"_a, "clicks"_a, "not_clicks"_a, "segmenter"_a.none());

  m.def("_reconstruct",
        [](const Scene& scene, const std::string& length, int steps, int height, bool eval, int64_t max_splats,
           int sh_degree, uint64_t seed, const PyGaussians* start, const std::string& device,
           const std::string& lpips_vgg, const std::function<void(int, double, double, double, int64_t)>& progress) {
          ReconstructOptions o;
          o.lpips = lpips_scorer(lpips_vgg);
          o.training = reconstruct_training(length, steps);
          o.training.sh_degree = sh_degree;
          o.training.seed = seed;
          if (progress)
            o.training.progress = [progress](const RefineProgress& p) {
              progress(p.step, p.fraction, p.loss, p.eta_s, p.gaussians);
            };
          o.height = height;
          o.eval = eval;
          if (eval && scene.test_views.empty())
            fail("reconstruct: eval=True scores held-out views: load the scene with hold_out_every=8, keep_object=True");
          o.max_splats = max_splats;
          if (start) o.start = in_scene_frame(start->set, start->normalization);
          o.device = resolve_device(device);
          PyGaussians out;
          {
            nb::gil_scoped_release release;
            const ReconstructResult r = reconstruct_scene(scene, o);
            out.set = r.gaussians.to(torch::kCPU);
            out.reconstruct_report = reconstruct_report(r, o).dump();
          }
          return out;
        },
        "scene"_a, "length"_a, "steps"_a, "height"_a, "eval"_a, "max_splats"_a, "sh_degree"_a, "seed"_a,
        "start"_a.none(), "device"_a, "lpips_vgg"_a, "progress"_a.none());

  m.def("_read_splats", [](const std::string& path) {
    PyGaussians g;
    nb::gil_scoped_release release;
    g.set = gaussians_from_splats(read_splats(path));
    return g;
  });

  nb::class_<PySegmenter>(m, "Segmenter")
      .def("__init__",
           [](PySegmenter* p, const std::string& path, const std::string& precision) {
             nb::gil_scoped_release release;
             // "auto", "mobile-sam" (the cache's) or a file, as the commands' --segmenter.
             const auto file = segmenter_path(path.empty() ? "auto" : path);
             if (!file) fail("Segmenter: no segmentation network in the cache; bring one with ii.models.get(\"mobile-sam\")");
             new (p) PySegmenter{std::make_shared<const Segmenter>(Segmenter::load(*file, parse_segmenter_precision(precision)))};
           },
           "path"_a, "precision"_a)
      .def_prop_ro("description", [](const PySegmenter& s) { return s.segmenter->description(); })
      .def_prop_ro("file", [](const PySegmenter& s) { return s.segmenter->file().string(); })
      .def_prop_ro("precision", [](const PySegmenter& s) { return std::string(s.segmenter->bf16() ? "bf16" : "fp32"); })
      .def("_segment",
           [](const PySegmenter& s, const AnyArray& image, const std::vector<std::pair<double, double>>& clicks,
              const std::vector<std::pair<double, double>>& not_clicks) {
             const Image photo = image_of(image, "image", 3);
             ClickedMask clicked;
             {
               nb::gil_scoped_release release;
               clicked = mask_from_clicks(*s.segmenter, photo, clicks_of(clicks), clicks_of(not_clicks));
             }
             return std::make_pair(array_of(clicked.mask), clicked.describe(*s.segmenter).dump());
           },
           "image"_a, "clicks"_a, "not_clicks"_a);

  nb::class_<Predictor>(m, "Predictor")
      .def("__init__",
           [](Predictor* p, const std::string& checkpoint, const std::string& device, const std::string& precision) {
             nb::gil_scoped_release release;
             const Runtime r = python_runtime(device, precision);
             new (p) Predictor(checkpoint, r.device, r.precision);
           },
           "checkpoint"_a, "device"_a, "precision"_a)
      .def_prop_ro("model", &Predictor::model_name)
      .def_prop_ro("device", [](const Predictor& p) { return p.device().str(); })
      .def_prop_ro("precision", [](const Predictor& p) { return std::string(precision_name(p.precision())); })
      .def_prop_ro("_describe", [](const Predictor& p) { return p.describe().dump(); })
      .def("_predict",
           [](const Predictor& p, const Scene& scene, const std::vector<std::string>& context, int views,
              const nb::object& reference, const std::string& reference_view, int height, bool keep_object,
              const std::map<std::string, AnyArray>& masks, const std::map<std::string, std::string>& geometry,
              const std::string& inpainter) {
             auto input = std::make_shared<SceneInputOptions>(
                 input_options(context, views, reference, reference_view, height, keep_object, masks));
             input->inpainter = inpainter_from_flag(inpainter, "ns");
             for (const auto& [name, text] : geometry) set_geometry_setting(input->geometry, name, text);
             PyGaussians g;
             {
               nb::gil_scoped_release release;
               auto prediction = std::make_shared<const Prediction>(p.predict(scene, *input));
               g.set = prediction->gaussians();
               g.normalization = prediction->input.normalization;
               g.prediction = std::move(prediction);
             }
             g.input = std::move(input);
             return g;
           },
           "scene"_a, "context"_a, "views"_a, "reference"_a.none(), "reference_view"_a, "height"_a, "keep_object"_a,
           "masks"_a, "geometry"_a, "inpainter"_a);

  m.def("_masks_from_one",
        [](const Scene& scene, const std::string& view, const nb::object& region,
           const std::vector<std::pair<double, double>>& clicks, const std::vector<std::pair<double, double>>& not_clicks,
           const PySegmenter* segmenter, const Predictor* predictor, int height, int views,
           const std::optional<std::array<double, 4>>& box) {
          const View* v = &view_of(scene, view);
          OneMask request;
          request.view = view;
          request.clicks = clicks_of(clicks);
          request.not_clicks = clicks_of(not_clicks);
          if (box) {
            if ((*box)[2] <= (*box)[0] || (*box)[3] <= (*box)[1])
              fail("box=({}, {}, {}, {}): expected (x0, y0, x1, y1) with x1 > x0 and y1 > y0", (*box)[0], (*box)[1],
                   (*box)[2], (*box)[3]);
            request.box = *box;
          }
          if (segmenter) request.segmenter = segmenter->segmenter;
          else if (!not_clicks.empty() && !box)
            fail("not_click= needs segmenter= or box=: the colour growth takes no such points");
          if (!clicks.empty() || box) {
            // the clicks select
          } else if (nb::isinstance<nb::str>(region) || nb::hasattr(region, "__fspath__"))
            request.region = read_region_mask(nb::cast<std::string>(nb::str(region)), *v);
          else
            request.region = image_of(nb::cast<AnyArray>(region), "region", 1);
          SceneInputOptions options;
          options.preprocess.height = height;
          options.num_views = views;
          SceneMasks masks;
          {
            nb::gil_scoped_release release;
            PredictorSource source;  // none: the library's error says which depth sources were missing
            if (predictor) source = [predictor]() -> const Predictor& { return *predictor; };
            masks = masks_from_one(scene, request, source, options);
          }
          std::map<std::string, nb::object> out;
          for (const auto& [name, mask] : masks.masks) out[name] = array_of(mask);
          return std::make_pair(out, masks.describe(request).dump());
        },
        "scene"_a, "view"_a, "region"_a.none(), "clicks"_a, "not_clicks"_a, "segmenter"_a.none(), "predictor"_a.none(),
        "height"_a, "views"_a, "box"_a.none() = nb::none());

  m.def("_evaluate",
        [](const std::string& scene, const std::string& out, const std::string& method,
           const std::optional<std::string>& checkpoint, const std::optional<std::string>& gaussians,
           const std::optional<std::string>& reference, const std::vector<std::string>& context, int views,
           int height, int hold_out_every, bool keep_object, const std::string& refine, const std::string& device,
           bool report) {
          EvalOptions o;
          o.scene_dir = scene;
          o.out = out;
          o.method = parse_eval_method(method);
          if (gaussians) o.gaussians = *gaussians;
          else if (o.method == EvalMethod::model) o.checkpoint = checkpoint.value_or("");
          if (reference) o.reference = *reference;
          o.context = context;
          o.num_views = views;
          o.height = height;
          o.scene.hold_out_every = hold_out_every;
          o.keep_object = keep_object;
          o.scene.hold_out_whole = keep_object;
          o.write_report = report;
          const Runtime r = python_runtime(device, "auto");
          o.device = r.device;
          o.precision = r.precision;
          const RefineOptions refine_options = refine_setting(refine.empty() ? "0" : refine);
          if (refine_requested(refine_options))
            o.after_prediction = [refine_options](const Scene& s, const Prediction& p, const SceneInputOptions& input,
                                                  GaussianSet g, nlohmann::json& report) {
              report["refine"] = nlohmann::json::object();
              return refine_prediction(s, p, input, g, refine_options, report["refine"]);
            };
          nb::gil_scoped_release release;
          return run_evaluation(o).dump();
        },
        "scene"_a, "out"_a, "method"_a, "checkpoint"_a.none(), "gaussians"_a.none(), "reference"_a.none(),
        "context"_a, "views"_a, "height"_a, "hold_out_every"_a, "keep_object"_a, "refine"_a, "device"_a, "report"_a);
}

}  // namespace ii::python
