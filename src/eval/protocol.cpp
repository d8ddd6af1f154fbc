#include "eval/protocol.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <future>
#include <limits>
#include <map>
#include <set>

#include <fmt/core.h>
#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/files.h"
#include "common/parallel.h"
#include "common/stage_times.h"
#include "common/stopwatch.h"
#include "data/image_ops.h"
#include "data/inpaint2d.h"
#include "data/masks.h"
#include "data/preprocess.h"
#include "data/view_selection.h"
#include "eval/fid.h"
#include "eval/inception.h"
#include "eval/lpips.h"
#include "eval/report.h"
#include "eval/truth_reference.h"
#include "gaussians/gaussians.h"
#include "io/image.h"
#include "io/splat_file.h"
#include "model/default_model.h"
#include "model/device.h"
#include "predict/predictor.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace ii {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The metric networks: each either loaded or unavailable with the reason.
struct MetricNetworks {
  std::optional<Lpips> lpips_vgg, lpips_alex;
  std::optional<InceptionFeatures> inception;
  std::string lpips_vgg_reason, inception_reason;
};

std::optional<fs::path> heads_file(const EvalOptions& o, LpipsNet net) {
  if (!o.lpips_heads_dir) return std::nullopt;
  return *o.lpips_heads_dir / (std::string(lpips_net_name(net)) + ".safetensors");
}

MetricNetworks load_metric_networks(const EvalOptions& o, const torch::Device& device) {
  MetricNetworks m;
  // A file the user named (option or environment) that fails to load is an error; a file
  // not named at all only makes the metric unavailable.
  if (lpips_backbone_path(LpipsNet::vgg, o.lpips_vgg)) {
    m.lpips_vgg.emplace(Lpips::load(LpipsNet::vgg, o.lpips_vgg, heads_file(o, LpipsNet::vgg)));
    m.lpips_vgg->to(device);
  } else {
    m.lpips_vgg_reason = lpips_missing_backbone_message(LpipsNet::vgg);
  }
  if (lpips_backbone_path(LpipsNet::alex, o.lpips_alex)) {
    m.lpips_alex.emplace(Lpips::load(LpipsNet::alex, o.lpips_alex, heads_file(o, LpipsNet::alex)));
    m.lpips_alex->to(device);
  }
  if (auto file = inception_weights_path(o.inception)) {
    m.inception.emplace(InceptionFeatures::load(*file));
    m.inception->to(device);
  } else {
    m.inception_reason = inception_missing_message();
  }
  return m;
}

// Each context view's own Gaussians (one per pixel) rendered at its own camera against what the
// network saw there, outside its mask: a one-Gaussian-per-pixel predictor should give its inputs
// back nearly exactly, whatever its depth; blur and smears from the Gaussians' sizes and
// opacities show here.
json own_views(const Prediction& p, const GaussianSet& g) {
  torch::NoGradGuard no_grad;
  json views = json::array();
  // g's rows: each view's pixels in turn (the maps' order), then those past the frames.
  const int64_t pixels = p.maps().depth.size(3) * p.maps().depth.size(4);
  const torch::Tensor view_of_row = torch::arange(g.size(), g.means.device()).div(pixels, "floor");
  double sum = 0;
  for (size_t v = 0; v < p.input.views.size(); ++v) {
    const PreparedView& view = p.input.views[v];
    const GaussianSet own = select_rows(g, view_of_row.eq(static_cast<int64_t>(v)));
    RenderCamera rc;
    rc.camera = p.input.normalization.apply(view.camera);
    const torch::Tensor rendered = render(own, rc).rgb.permute({2, 0, 1}).unsqueeze(0).to(torch::kCPU);
    const torch::Tensor photo = image_to_tensor(view.rgb);
    torch::Tensor outside = torch::ones({1, 1, view.rgb.height, view.rgb.width});
    if (view.mask) outside = (image_to_tensor(*view.mask) <= 0.5).to(torch::kFloat32);
    const double db = masked_psnr(rendered, photo, outside)[0].item<double>();
    sum += db;
    views.push_back({{"view", view.name}, {"psnr_outside_mask", metric_json(db)}});
  }
  return {{"views", views},
          {"mean_psnr_outside_mask", metric_json(sum / static_cast<double>(p.input.views.size()))},
          {"definition", "each context view's own Gaussians rendered at its camera against its working image "
                         "outside its mask (the reference: against the picture the network saw)"}};
}

std::string scene_task(const Scene& scene);  // below

// The predicted Gaussians, float32 on `render_on` (where the rasterizer runs).
GaussianSet predict_gaussians(const Scene& scene, const EvalOptions& o, const torch::Device& render_on,
                              json& info, StageTimes& stages) {
  stages.restart_lap();
  if (o.gaussians) {
    const SplatCloud cloud = read_splats(*o.gaussians);
    info["source"] = "gaussians";
    info["ply"] = o.gaussians->string();
    stages.lap("read gaussians");
    GaussianSet g = gaussians_from_splats(cloud, o.sh_degree).to(render_on);
    // Test views are rendered in the pose-normalised frame, as the network's Gaussians are.
    if (!o.gaussians_normalized) g = in_normalized_frame(g, scene_normalization(scene));
    info["frame"] = o.gaussians_normalized ? "normalized" : "scene";
    stages.lap("gaussians to the renderer");
    return g;
  }
  info["source"] = "network";
  const std::string checkpoint = o.checkpoint ? o.checkpoint->string() : "";
  spdlog::info("loading the model {}", checkpoint.empty() ? kDefaultModelName : checkpoint);
  const Predictor predictor(checkpoint, o.device, o.precision);
  const json model = predictor.describe();
  info["checkpoint"] = model["checkpoint"];
  info["checkpoint_format"] = model["format"];
  info["config"] = model["config"];
  if (model.contains("cpu")) info["cpu"] = model["cpu"];
  stages.merge(predictor.load_stages(), "load model: ");
  stages.restart_lap();

  SceneInputOptions opts;
  opts.context = o.context;
  opts.num_views = o.num_views;
  opts.reference = o.reference;
  opts.preprocess.height = o.height;
  opts.inpainter = o.inpainter;
  opts.inpaint_grow = o.inpaint_grow;
  opts.reference_view = o.reference_view;
  opts.keep_object = o.keep_object;
  opts.geometry = o.geometry;
  if (scene_task(scene) == "insert" || (o.edit && o.edit->propagation.mode == EditMode::Insert))
    opts.geometry = opts.geometry.for_insertion();
  if (o.edit) {
    spdlog::info("masks for every view from the region on {}", o.edit->view);
    const SceneMasks masks =
        masks_from_one(scene, *o.edit, [&]() -> const Predictor& { return predictor; }, opts, &stages);
    masks.apply_to(opts, *o.edit);
    info["edit"] = masks.describe(*o.edit);
    stages.restart_lap();
  }
  spdlog::info("running the network ({})", precision_name(o.precision));
  const Prediction p = predictor.predict(scene, opts);
  stages.merge(p.stages);
  stages.restart_lap();
  info["context"] = json::array();
  for (const PreparedView& v : p.input.views) info["context"].push_back(v.name);
  info["reference"] = p.input.reference_source;
  info["inpainter"] = p.input.reference_inpainter;
  info["geometry"] = p.describe_geometry();
  GaussianSet g = p.gaussians();
  for (torch::Tensor* t : {&g.means, &g.quats, &g.scales, &g.opacities, &g.colors})
    *t = t->to(render_on, torch::kFloat32);
  synchronize(render_on);
  stages.lap("gaussians to the renderer");
  info["own_views"] = own_views(p, g);
  stages.lap("own views");
  if (o.after_prediction) {
    g = o.after_prediction(scene, p, opts, g, info["after_prediction"]);
    stages.lap("refine");
  }
  return g;
}

struct Averager {
  double sum = 0;
  int count = 0;
  void add(double v) {
    if (std::isnan(v)) return;
    sum += v;
    ++count;
  }
  double mean() const { return count ? sum / count : kNaN; }
};

FeatureMatrix to_matrix(const std::vector<std::vector<float>>& rows) {
  FeatureMatrix m(static_cast<Eigen::Index>(rows.size()), rows.empty() ? 0 : static_cast<Eigen::Index>(rows[0].size()));
  for (size_t i = 0; i < rows.size(); ++i)
    for (size_t j = 0; j < rows[i].size(); ++j)
      m(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = rows[i][j];
  return m;
}

std::vector<float> row_of(const torch::Tensor& features, int64_t i) {
  const torch::Tensor r = features[i].to(torch::kCPU, torch::kFloat32).contiguous();
  return std::vector<float>(r.data_ptr<float>(), r.data_ptr<float>() + r.numel());
}

// FID and KID of two feature sets into `set`, or the reason they cannot be computed.
void distribution_metrics(const std::vector<std::vector<float>>& real, const std::vector<std::vector<float>>& fake,
                          const std::string& fid_key, const std::string& kid_key, json& set, json& unavailable) {
  if (real.size() < 2 || fake.size() < 2) {
    const std::string reason = fmt::format("needs at least 2 images per set, have {} and {}", real.size(), fake.size());
    set[fid_key] = nullptr;
    set[kid_key] = nullptr;
    unavailable[fid_key] = reason;
    unavailable[kid_key] = reason;
    return;
  }
  const FeatureMatrix x = to_matrix(real), y = to_matrix(fake);
  set[fid_key] = metric_json(frechet_distance(x, y));
  KidOptions ko;
  // With sets no larger than one subset every subset is the whole set: one suffices.
  if (std::min(x.rows(), y.rows()) <= ko.subset_size) ko.subsets = 1;
  const KidResult kid = kernel_inception_distance(x, y, ko);
  set[kid_key] = metric_json(kid.mean);
  set[kid_key + "_std"] = metric_json(kid.std);
  set[kid_key + "_subsets"] = kid.subsets;
  set[kid_key + "_subset_size"] = kid.subset_size;
}

// A synthetic scene's synth.json (an empty object for captures).
json synth_description(const Scene& scene) {
  const fs::path file = scene.root / "synth.json";
  if (!fs::exists(file)) return json::object();
  try {
    json j = json::parse(read_file_text(file));
    if (!j.is_object()) fail_file(file, "not a JSON object");
    return j;
  } catch (const json::exception& e) {
    fail_file(file, "not valid JSON: {}", e.what());
  }
}

// What a scene was made for: synthetic scenes say it ("remove" or "insert"), captures are
// removal scenes.
std::string scene_task(const Scene& scene) { return synth_description(scene).value("task", "remove"); }

// The insertion baselines' inputs: the test views with nothing inserted and, for the sticker,
// the edited reference with its region and background depth.
struct InsertionBaseline {
  EvalMethod method;
  fs::path original;  // folder of the test views before the edit
  View reference;
  Image reference_image, region, depth;

  Image predict(const View& view, const PreprocessOptions& preprocess) const {
    View before = view;
    before.image_path = original / view.image_path.filename();
    if (!fs::exists(before.image_path))
      fail_file(before.image_path, "missing: the test view {} with nothing inserted", view.name);
    Image image = load_view_image(before);
    if (method == EvalMethod::sticker)
      image = sticker_view(image, view.camera, reference_image, region, depth, reference.camera);
    return to_working_size(image, working_size(image.width, image.height, preprocess));
  }
};

std::optional<InsertionBaseline> insertion_baseline(const Scene& scene, const EvalOptions& o) {
  if (o.method != EvalMethod::floor && o.method != EvalMethod::sticker) return std::nullopt;
  InsertionBaseline b;
  b.method = o.method;
  b.original = scene.root / "original";
  if (!fs::is_directory(b.original))
    fail("{}: --method {} needs original/ (the test views with nothing inserted, as synth --task insert writes)",
         scene.root.string(), eval_method_name(o.method));
  if (o.method == EvalMethod::floor) return b;
  if (!o.reference) fail("--method sticker needs --reference: the reference view with the object painted in");
  std::string name = o.reference_view;
  if (name.empty() && !o.context.empty()) name = o.context.front();
  if (name.empty()) name = synth_description(scene).value("reference", "");
  if (name.empty()) fail("--method sticker needs the reference view: give --reference-view or --context");
  b.reference = scene.views.at(static_cast<size_t>(input_view_index(scene, name, "reference view")));
  b.reference_image = read_image_rgb(*o.reference);
  const auto region = load_view_mask(b.reference);
  if (!region) fail("--method sticker: reference view {} has no mask (its edit region)", name);
  b.region = *region;
  const auto depth = load_view_depth(scene, b.reference);
  if (!depth) fail("--method sticker: no depth/{}.npy in {}", name, scene.root.string());
  b.depth = *depth;
  return b;
}

}  // namespace

const char* eval_method_name(EvalMethod method) {
  switch (method) {
    case EvalMethod::model: return "model";
    case EvalMethod::telea: return "telea";
    case EvalMethod::mean_fill: return "mean-fill";
    case EvalMethod::floor: return "floor";
    case EvalMethod::sticker: return "sticker";
  }
  return "?";
}

EvalMethod parse_eval_method(const std::string& name) {
  if (name == "model") return EvalMethod::model;
  if (name == "telea") return EvalMethod::telea;
  if (name == "mean-fill") return EvalMethod::mean_fill;
  if (name == "floor") return EvalMethod::floor;
  if (name == "sticker") return EvalMethod::sticker;
  fail("--method: unknown method '{}' (expected model, telea, mean-fill, floor or sticker)", name);
}

torch::Tensor quantize_image(const torch::Tensor& images, const std::string& mode) {
  if (mode == "none") return images;
  if (mode != "round" && mode != "truncate")
    fail("--quantize: unknown mode '{}' (expected round, truncate or none)", mode);
  const torch::Tensor scaled = images.clamp(0, 1) * 255;
  return (mode == "round" ? torch::floor(scaled + 0.5) : torch::floor(scaled)) / 255;
}

Image quantize_image(const Image& image, const std::string& mode) {
  if (mode == "none") return image;
  if (mode != "round" && mode != "truncate")
    fail("--quantize: unknown mode '{}' (expected round, truncate or none)", mode);
  // The tensor form's arithmetic in the same float steps, without LibTorch: test views are
  // quantised on the threads that decode them, beside LibTorch's own.
  const float half = mode == "round" ? 0.5f : 0.f;
  Image out = image;
  for (float& v : out.pixels) {
    const float scaled = std::clamp(v, 0.f, 1.f) * 255.f;
    v = std::floor(scaled + half) / 255.f;
  }
  return out;
}

Image mean_fill(const Image& rgb, const Image& mask, int ring_width) {
  if (mask.width != rgb.width || mask.height != rgb.height || mask.channels != 1)
    fail("mean fill: the mask ({}x{}, {} channels) does not fit the {}x{} image", mask.width, mask.height,
         mask.channels, rgb.width, rgb.height);
  if (ring_width < 1) fail("mean fill: the ring width must be at least 1 pixel, got {}", ring_width);
  Image inside = mask;
  for (float& v : inside.pixels) v = v > 0.5f ? 1.f : 0.f;
  const Image dilated = dilate_mask(inside, 1, 2 * ring_width + 1);
  double sum[3] = {0, 0, 0};
  int64_t count = 0;
  for (int y = 0; y < rgb.height; ++y)
    for (int x = 0; x < rgb.width; ++x)
      if (dilated.at(y, x) > 0.5f && inside.at(y, x) < 0.5f) {
        for (int c = 0; c < 3; ++c) sum[c] += rgb.at(y, x, c);
        ++count;
      }
  float fill[3] = {0.5f, 0.5f, 0.5f};
  if (count > 0)
    for (int c = 0; c < 3; ++c) fill[c] = static_cast<float>(sum[c] / count);
  Image out = rgb;
  for (int y = 0; y < rgb.height; ++y)
    for (int x = 0; x < rgb.width; ++x)
      if (inside.at(y, x) > 0.5f)
        for (int c = 0; c < 3; ++c) out.at(y, x, c) = fill[c];
  return out;
}

Image sticker_view(const Image& floor, const Camera& view, const Image& reference, const Image& region,
                   const Image& depth, const Camera& reference_camera) {
  const Intrinsics& R = reference_camera.K;
  for (const Image* image : {&reference, &region, &depth})
    if (image->width != R.width || image->height != R.height)
      fail("sticker: the reference's images must be {}x{} (the reference camera), got {}x{}", R.width, R.height,
           image->width, image->height);
  if (floor.width != view.K.width || floor.height != view.K.height)
    fail("sticker: the floor image is {}x{}, its camera {}x{}", floor.width, floor.height, view.K.width, view.K.height);
  const Eigen::Matrix4d ref_c2w = opengl_to_opencv(reference_camera.c2w), w2c = view.w2c_opencv();
  const Eigen::Matrix4d ref_to_view = w2c * ref_c2w;
  Image out = floor;
  std::vector<float> nearest(static_cast<size_t>(floor.width) * floor.height, std::numeric_limits<float>::infinity());
  for (int y = 0; y < R.height; ++y)
    for (int x = 0; x < R.width; ++x) {
      const float d = depth.at(y, x);
      if (region.at(y, x) <= 0.5f || !(d > 0) || !std::isfinite(d)) continue;
      const Eigen::Vector4d local(d * (x + 0.5 - R.cx) / R.fx, d * (y + 0.5 - R.cy) / R.fy, d, 1);
      const Eigen::Vector4d p = ref_to_view * local;
      if (p.z() <= 0) continue;
      const double u = view.K.fx * p.x() / p.z() + view.K.cx - 0.5, v = view.K.fy * p.y() / p.z() + view.K.cy - 0.5;
      if (!(u > -2 && v > -2 && u < floor.width + 1 && v < floor.height + 1)) continue;
      const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
      for (int yy = y0; yy <= y0 + 1; ++yy)
        for (int xx = x0; xx <= x0 + 1; ++xx) {
          if (xx < 0 || yy < 0 || xx >= floor.width || yy >= floor.height) continue;
          float& z = nearest[static_cast<size_t>(yy) * floor.width + xx];
          if (p.z() >= z) continue;
          z = static_cast<float>(p.z());
          for (int c = 0; c < 3; ++c) out.at(yy, xx, c) = reference.at(y, x, c);
        }
    }
  return out;
}

std::optional<PixelBox> crop_around_mask(const Image& mask) {
  const auto box = mask_bounding_box(mask);
  if (!box) return std::nullopt;
  const int side = std::max(16, static_cast<int>(std::lround(1.2 * std::max(box->width(), box->height()))));
  return grow_box(*box, side, side, mask.width, mask.height);
}

namespace {

// A test view at the working size, its ground truth quantised as the predictions will be.
struct TestView {
  PreparedView prepared;
  Image truth;
};

// The test views in order, decoded `ahead` at a time on background threads: the CPU work that
// runs beside the renders.
class TestViewReader {
 public:
  TestViewReader(const std::vector<View>& views, const PreprocessOptions& preprocess, const std::string& quantize,
                 size_t ahead)
      : views_(views), preprocess_(preprocess), quantize_(quantize), ahead_(std::max<size_t>(1, ahead)) {}

  TestView next() {
    fill();
    TestView view = pending_.front().get();
    pending_.pop_front();
    fill();
    return view;
  }

 private:
  void fill() {
    for (; next_ < views_.size() && pending_.size() < ahead_; ++next_)
      pending_.push_back(std::async(std::launch::async, [this, &view = views_[next_]] {
        TestView t{prepare_view(view, preprocess_), {}};
        // The ground truth is rounded whatever the predictions' mode, unless nothing is.
        t.truth = quantize_ == "none" ? t.prepared.rgb : quantize_image(t.prepared.rgb, "round");
        return t;
      }));
  }

  const std::vector<View>& views_;
  const PreprocessOptions& preprocess_;
  const std::string quantize_;
  const size_t ahead_;
  size_t next_ = 0;
  std::deque<std::future<TestView>> pending_;
};

// Metric values computed on the device, read back in one transfer: on a GPU each value read
// waits for the device.
class DeviceValues {
 public:
  void add(const std::string& key, const torch::Tensor& value) {
    keys_.push_back(key);
    values_.push_back(value.reshape({}).to(torch::kDouble));
  }
  void add_nan(const std::string& key) { nan_keys_.push_back(key); }
  std::vector<std::pair<std::string, double>> read() const {
    std::vector<std::pair<std::string, double>> out;
    if (!values_.empty()) {
      const torch::Tensor read = torch::stack(values_).to(torch::kCPU);
      const double* v = read.data_ptr<double>();
      for (size_t i = 0; i < keys_.size(); ++i) out.emplace_back(keys_[i], v[i]);
    }
    for (const std::string& key : nan_keys_) out.emplace_back(key, kNaN);
    return out;
  }

 private:
  std::vector<std::string> keys_, nan_keys_;
  std::vector<torch::Tensor> values_;
};

// What every test view's evaluation shares.
struct EvalRun {
  const EvalOptions& o;
  const Scene& scene;
  torch::Device device;                      // uploads, baselines and metrics
  std::optional<GaussianSet> gaussians;      // method model, on the rasterizer's device
  std::optional<InsertionBaseline> baseline;
  PoseNormalization normalization;
  PreprocessOptions preprocess;
};

// Inception features of ground truths and predictions (whole views and crops around the mask).
struct FeatureSets {
  std::vector<std::vector<float>> real, fake, real_crops, fake_crops;
};

struct TestViewResults {
  json views = json::array();
  std::map<std::string, Averager> means;
  FeatureSets features;
  int working_width = 0, working_height = 0;
  int64_t uncovered_pixels = 0;  // method model: region pixels where nothing renders, all views
  int views_uncovered = 0;       // ... the views that have any
};

// The method's prediction of one test view on the device, quantised as the official pipeline
// saves it; the device has finished it when this returns (its time is the view's).
struct TestViewPrediction {
  torch::Tensor rgb;    // (1, 3, H, W) on the device
  torch::Tensor alpha;  // (1, 1, H, W), method model only: where nothing renders the background shows
};

TestViewPrediction predict_test_view(const EvalRun& r, const View& view, const TestView& t) {
  torch::Tensor a, alpha;
  if (r.o.method == EvalMethod::model) {
    RenderCamera rc;
    rc.camera = r.normalization.apply(t.prepared.camera);
    const RenderOutput out = render(*r.gaussians, rc);
    a = out.rgb.permute({2, 0, 1}).unsqueeze(0).to(r.device);
    alpha = out.alpha.permute({2, 0, 1}).unsqueeze(0).to(r.device);
  } else if (r.baseline) {
    a = to_device(image_to_tensor(r.baseline->predict(view, r.preprocess)), r.device);
  } else {
    const char* method = eval_method_name(r.o.method);
    if (!t.prepared.mask)
      fail("{}: test view {} has no mask; --method {} fills the masked region", r.o.scene_dir.string(), view.name,
           method);
    if (view.shows_object)
      fail("{}: --method {} fills the mask of the ground truth itself; held-out views that show the object "
           "(--hold-out-every) compare nothing else",
           r.o.scene_dir.string(), method);
    const Image& truth = t.truth;
    a = to_device(image_to_tensor(r.o.method == EvalMethod::telea ? inpaint_telea(truth, *t.prepared.mask)
                                                                   : mean_fill(truth, *t.prepared.mask, r.o.ring_width)),
                  r.device);
  }
  a = quantize_image(a, r.o.quantize);
  synchronize(r.device);
  return {a, alpha};
}

// PSNR and SSIM and their masked, outside-the-mask and bounding-box variants of one view,
// queued on the device (one SSIM map serves every SSIM).
void queue_image_metrics(const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& m,
                         const std::optional<Image>& mask, bool shows_object, DeviceValues& values) {
  const torch::Tensor map = ssim_map(a, b);
  if (m.defined()) {
    // Held-out views show the object the prediction removed: only the rest compares.
    const torch::Tensor outside = (m <= 0.5).to(m.dtype());
    values.add("outside_psnr", masked_psnr(a, b, outside)[0]);
    values.add("outside_ssim", masked_ssim_of_map(map, outside)[0]);
    values.add("mask_pixels", (m > 0.5).sum());
  }
  if (shows_object) return;
  values.add("psnr", psnr(a, b)[0]);
  values.add("ssim", map.flatten(1).mean(1)[0]);
  if (!m.defined()) return;
  values.add("masked_psnr", masked_psnr(a, b, m)[0]);
  values.add("masked_ssim", masked_ssim_of_map(map, m)[0]);
  if (const auto box = mask_bounding_box(*mask)) {  // the host's copy of the mask: no wait
    const torch::Tensor both = box_psnr_ssim(a, b, *box, map);
    values.add("box_psnr", both[0]);
    values.add("box_ssim", both[1]);
  } else {
    values.add_nan("box_psnr");
    values.add_nan("box_ssim");
  }
}

// LPIPS values of one view, queued on the device.
void queue_lpips(const MetricNetworks& nets, const torch::Tensor& a, const torch::Tensor& b, const torch::Tensor& m,
                 DeviceValues& values) {
  const torch::Tensor as = a * 2 - 1, bs = b * 2 - 1;
  if (nets.lpips_vgg) {
    values.add("lpips", nets.lpips_vgg->forward(as, bs)[0]);
    if (m.defined()) values.add("masked_lpips", nets.lpips_vgg->masked(as, bs, m)[0]);
  }
  if (nets.lpips_alex) values.add("lpips_alex", nets.lpips_alex->forward(as, bs)[0]);
}

void add_inception_features(const InceptionFeatures& inception, const torch::Tensor& a, const torch::Tensor& b,
                            const std::optional<Image>& mask, FeatureSets& sets) {
  const torch::Tensor pair = torch::cat({b, a}, 0);
  const torch::Tensor f = inception.forward(pair);
  sets.real.push_back(row_of(f, 0));
  sets.fake.push_back(row_of(f, 1));
  if (mask)
    if (const auto box = crop_around_mask(*mask)) {
      const torch::Tensor fc = inception.forward(crop_to_box(pair, *box));
      sets.real_crops.push_back(row_of(fc, 0));
      sets.fake_crops.push_back(row_of(fc, 1));
    }
}

// The view's render (and contact sheet) encoded and written behind the main work; their time
// is recorded as "behind" stages, the wait for a free writer as the main thread's.
void queue_view_files(const EvalRun& r, const TestView& t, const Image& predicted, const std::string& name,
                      BackgroundJobs& writes, StageTimes& stages, json& v) {
  const fs::path out = r.o.out;
  const std::string render_file = "renders/" + name + ".png";
  writes.add([path = out / render_file, predicted, &stages] {
    stages.time("write renders", [&] { write_png(path, predicted); }, /*behind=*/true);
  });
  v["files"] = {{"render", render_file}};
  if (!r.o.write_report) return;
  const std::string sheet_file = "sheets/" + name + ".png";
  writes.add([path = out / sheet_file, truth = t.truth, predicted, mask = t.prepared.mask, &stages] {
    stages.time(
        "write contact sheets",
        [&] {
          write_png(path,
                    contact_sheet({truth, predicted, error_map(truth, predicted), with_mask_outline(predicted, mask)}));
        },
        /*behind=*/true);
  });
  v["files"]["sheet"] = sheet_file;
}

void log_view(const View& view, size_t index, size_t count, const json& v, bool masked) {
  if (view.shows_object)
    spdlog::info("[{}/{}] {} (held out, shows the object): PSNR outside the mask {}", index, count, view.name,
                 metric_cell(v["outside_psnr"], 2));
  else
    spdlog::info("[{}/{}] {}: PSNR {} SSIM {}{}", index, count, view.name, metric_cell(v["psnr"], 2),
                 metric_cell(v["ssim"], 4), masked ? ", masked PSNR " + metric_cell(v["masked_psnr"], 2) : std::string());
}

// A view whose metric values are still on the device: read once the next view's render has
// waited for the device anyway (one wait a view instead of two).
struct MeasuredView {
  const View* view = nullptr;
  size_t index = 0;
  bool masked = false;
  json v;
  DeviceValues values;
};

// Every test view: decoded ahead, predicted, measured, its files written behind. Each view's
// images stay on the device from the upload (or the render) to the metrics; only the
// prediction comes back, to be written.
TestViewResults evaluate_test_views(const EvalRun& r, const MetricNetworks& nets, StageTimes& stages) {
  const fs::path out = r.o.out;
  fs::create_directories(out / "renders");
  if (r.o.write_report) fs::create_directories(out / "sheets");
  const ThreadPlan plan = thread_plan();
  TestViewReader reader(r.scene.test_views, r.preprocess, r.o.quantize, static_cast<size_t>(plan.files));
  // Declared after the reader: destroyed first, so a failed view waits for its writes.
  BackgroundJobs writes(static_cast<size_t>(plan.files));
  const std::string predict_stage =
      r.o.method == EvalMethod::model ? "render" : fmt::format("baseline {}", eval_method_name(r.o.method));
  TestViewResults results;
  const size_t count = r.scene.test_views.size();
  auto put = [&](json& v, const std::string& key, double value) {
    if (key == "mask_pixels" || key == "uncovered_pixels") {
      v[key] = static_cast<int64_t>(value);
      if (key == "uncovered_pixels") {
        results.uncovered_pixels += static_cast<int64_t>(value);
        results.views_uncovered += value > 0 ? 1 : 0;
      }
      return;
    }
    v[key] = metric_json(value);
    results.means[key].add(value);
  };
  std::optional<MeasuredView> measured;
  auto finish_measured = [&] {
    if (!measured) return;
    for (const auto& [key, value] : measured->values.read()) put(measured->v, key, value);
    log_view(*measured->view, measured->index + 1, count, measured->v, measured->masked);
    results.views.push_back(std::move(measured->v));
    measured.reset();
  };
  for (size_t i = 0; i < count; ++i) {
    const View& view = r.scene.test_views[i];
    stages.restart_lap();
    const TestView t = reader.next();
    results.working_width = t.truth.width;
    results.working_height = t.truth.height;
    stages.lap("decode test views (waited)");
    const torch::Tensor b = image_to_device(t.truth, r.device);
    torch::Tensor m;
    if (t.prepared.mask) m = image_to_device(*t.prepared.mask, r.device);
    stages.lap("upload test views");
    const TestViewPrediction prediction = predict_test_view(r, view, t);
    const torch::Tensor& a = prediction.rgb;
    const double predict_ms = stages.lap(predict_stage);
    const Image predicted = tensor_to_image(a);
    stages.lap("download renders");
    finish_measured();  // the render waited for the previous view's metrics too: read at no wait

    MeasuredView next{&view, i, t.prepared.mask.has_value(), {{"name", view.name}, {"predict_ms", predict_ms}}, {}};
    {
      torch::NoGradGuard no_grad;
      queue_image_metrics(a, b, m, t.prepared.mask, view.shows_object, next.values);
      // The region's pixels where nothing renders (the background shows): a fill that left a gap.
      if (m.defined() && prediction.alpha.defined() && !view.shows_object)
        next.values.add("uncovered_pixels", (m > 0.5).logical_and(prediction.alpha < 0.5).sum());
      stages.lap("image metrics");
      if (!view.shows_object && (nets.lpips_vgg || nets.lpips_alex)) {
        queue_lpips(nets, a, b, m, next.values);
        stages.lap("lpips");
      }
      if (!view.shows_object && nets.inception) {
        add_inception_features(*nets.inception, a, b, t.prepared.mask, results.features);
        stages.lap("inception features");
      }
    }
    queue_view_files(r, t, predicted, view.name, writes, stages, next.v);
    stages.lap("write files (waited)");
    measured = std::move(next);
  }
  stages.restart_lap();
  finish_measured();
  stages.lap("image metrics");
  writes.finish();
  stages.lap("write files (waited)");
  return results;
}

json mean_metrics(const std::map<std::string, Averager>& means, json& unavailable) {
  json mean = json::object();
  if (!means.count("psnr"))
    for (const char* key : {"psnr", "ssim", "masked_psnr", "masked_ssim", "lpips", "masked_lpips"})
      unavailable[key] =
          "every test view is a held-out view that shows the object (--hold-out-every): see outside_psnr, outside_ssim";
  for (const char* key : {"psnr", "ssim", "masked_psnr", "masked_ssim", "outside_psnr", "outside_ssim", "box_psnr",
                          "box_ssim", "lpips", "masked_lpips", "lpips_alex"}) {
    if (means.count(key))
      mean[key] = metric_json(means.at(key).mean());
    else if (unavailable.contains(key))
      mean[key] = nullptr;
  }
  if (!means.count("masked_psnr") && !unavailable.contains("masked_psnr")) {
    for (const char* key : {"masked_psnr", "masked_ssim"}) {
      mean[key] = nullptr;
      unavailable[key] = "no test view has a mask";
    }
  }
  return mean;
}

json set_metrics(const MetricNetworks& nets, const FeatureSets& features, json& unavailable) {
  json set = json::object();
  if (nets.inception) {
    distribution_metrics(features.real, features.fake, "fid", "kid", set, unavailable);
    distribution_metrics(features.real_crops, features.fake_crops, "c_fid", "c_kid", set, unavailable);
  } else {
    for (const char* k : {"fid", "kid", "c_fid", "c_kid"}) set[k] = nullptr;
  }
  return set;
}

json metric_definitions() {
  return {{"psnr", "-10 log10 MSE over all pixels and channels, images in [0,1]; \"inf\" for identical images"},
          {"ssim", "Gaussian window 11, sigma 1.5, K1 0.01, K2 0.03, valid positions, mean over channels"},
          {"masked_psnr", "PSNR over the pixels of the view's test mask"},
          {"masked_ssim", "SSIM map averaged over valid positions whose centre is in the mask"},
          {"outside_psnr", "PSNR over the pixels outside the view's mask (the only comparison on held-out views)"},
          {"outside_ssim", "SSIM map averaged over valid positions whose centre is outside the mask"},
          {"box_psnr", "PSNR on the mask's bounding box"},
          {"box_ssim", "SSIM on the mask's bounding box grown to at least 11x11"},
          {"lpips",
           "LPIPS v0.1 VGG, inputs in [-1,1], spatial average per stage (the official helper averages the upsampled "
           "spatial map: the same value when the sides are multiples of 16)"},
          {"masked_lpips", "both images multiplied by the mask, spatial LPIPS map averaged over the mask"},
          {"fid", "Frechet distance of pytorch-fid Inception-v3 pool features, ground truth vs predictions"},
          {"kid", "unbiased MMD^2, kernel (x.y/2048 + 1)^3"},
          {"c_fid", "FID on square crops around the mask (1.2 x the box's longer side)"},
          {"c_kid", "KID on the same crops"}};
}

// The method's and the protocol's computation: every stage but reading, decoding and writing
// files and loading networks; the figure `eval` prints and the device check compares.
double compute_ms(const StageTimes& stages) {
  static const std::set<std::string> compute = {"upload", "network", "gaussians to the renderer",
                                                "upload test views", "render", "image metrics", "lpips",
                                                "inception features", "fid/kid", "download renders"};
  double ms = 0;
  for (const StageTimes::Stage& s : stages.stages())
    if (!s.behind && (compute.count(s.name) || s.name.rfind("baseline ", 0) == 0)) ms += s.ms;
  return ms;
}

void check_eval_options(const EvalOptions& o) {
  quantize_image(Image(1, 1, 1), o.quantize);  // validates the mode before any work
  if (o.method == EvalMethod::model && o.checkpoint && o.gaussians)
    fail("eval: give either --checkpoint or --gaussians, not both");
  if (o.method != EvalMethod::model && (o.checkpoint || o.gaussians))
    fail("eval --method {} is a baseline without a model: drop --checkpoint/--gaussians", eval_method_name(o.method));
}

// The scene, with an object-free test view moved to the inputs when it is the reference (the
// ground-truth-reference protocol: its photo becomes the reference unless one is given).
Scene read_eval_scene(EvalOptions& o, json& prediction, StageTimes& stages) {
  spdlog::info("reading scene {}", o.scene_dir.string());
  Scene scene = load_scene(o.scene_dir, o.scene);
  const std::string reference = !o.context.empty() ? o.context.front() : o.reference_view;
  if (const auto truth = take_truth_reference(scene, reference)) {
    if (!o.reference && !o.keep_object) o.reference = truth->photo;
    prediction["reference_protocol"] = {
        {"kind", "ground truth"},
        {"view", truth->view},
        {"reference", o.reference ? o.reference->string() : "photo (object kept)"},
        {"note", "an object-free test view is the reference: its photo the reference image, its test mask the "
                 "region; it is not among the scored views"}};
    spdlog::info("object-free test view {} is the reference (its own photo); {} test views are scored", truth->view,
                 scene.test_views.size());
  } else if (o.gaussians && o.context.empty() && !o.reference_view.empty()) {
    // Splats are scored as they are: a reference named for them can only be the test view to
    // leave out, and a name that is none would be ignored.
    fail("{}: {} is not an object-free test view: with --gaussians the reference view names the test view the "
         "splats were filled from, which is then not scored",
         o.scene_dir.string(), o.reference_view);
  }
  if (scene.test_views.empty())
    fail("{}: no test views (SPIn-NeRF scenes list object-free ones by their masks in images_K/test_label/; "
         "--hold-out-every N holds out input views that have masks)",
         o.scene_dir.string());
  stages.lap("read scene");
  return scene;
}

// The region beside the whole image (the means), and the region's pixels where nothing renders.
json region_and_whole(const json& mean, const TestViewResults& results, bool rendered) {
  json j = json::object();
  for (const char* metric : {"psnr", "ssim"}) {
    const json whole = mean.value(metric, json()), region = mean.value(std::string("masked_") + metric, json());
    j[metric] = {{"whole", whole}, {"region", region}};
    if (whole.is_number() && region.is_number())
      j[metric]["region_minus_whole"] = region.get<double>() - whole.get<double>();
  }
  if (rendered)
    j["uncovered"] = {{"pixels", results.uncovered_pixels},
                      {"views", results.views_uncovered},
                      {"definition", "region pixels where the render's opacity is under 0.5 (the background shows)"}};
  return j;
}

}  // namespace

json run_evaluation(const EvalOptions& options) {
  Stopwatch total;
  StageTimes stages;
  check_eval_options(options);
  // A GPU given without an index (torch::kCUDA) is the first one: named so in the results and
  // equal to the device of the tensors made there.
  const torch::Device device = resolve_device(options.device.str());
  EvalOptions o = options;  // the reference may become a test view's photo
  json prediction = {{"method", eval_method_name(o.method)}};
  const Scene scene = read_eval_scene(o, prediction, stages);

  EvalRun r{o, scene, device, std::nullopt, insertion_baseline(scene, o), scene_normalization(scene), {}};
  r.preprocess.height = o.height;
  if (r.baseline) prediction["reference_view"] = r.baseline->reference.name;
  if (o.method == EvalMethod::model) {
    // Without the CUDA rasterizer kernels a GPU run renders on the CPU.
    r.gaussians = predict_gaussians(scene, o, render_device(device), prediction, stages);
    prediction["gaussians"] = r.gaussians->size();
  }

  stages.restart_lap();
  const MetricNetworks nets = load_metric_networks(o, device);
  json unavailable = json::object();
  if (!nets.lpips_vgg) {
    unavailable["lpips"] = nets.lpips_vgg_reason;
    unavailable["masked_lpips"] = nets.lpips_vgg_reason;
  }
  if (!nets.inception)
    for (const char* k : {"fid", "kid", "c_fid", "c_kid"}) unavailable[k] = nets.inception_reason;
  stages.lap("load metric networks");

  const TestViewResults results = evaluate_test_views(r, nets, stages);
  const json mean = mean_metrics(results.means, unavailable);
  stages.restart_lap();
  const json set = set_metrics(nets, results.features, unavailable);
  if (nets.inception) stages.lap("fid/kid");

  const ThreadPlan plan = thread_plan();
  json metrics = {{"protocol", "spin-nerf"},
                  {"scene", scene.root.string()},
                  {"format", scene.format},
                  {"method", eval_method_name(o.method)},
                  {"task", scene_task(scene)},
                  {"prediction", prediction},
                  {"working_size", {results.working_width, results.working_height}},
                  {"quantize", o.quantize},
                  {"device", device.str()},
                  {"threads", {{"cores", plan.cores}, {"compute", plan.compute}, {"files", plan.files}}},
                  {"views", results.views},
                  {"mean", mean},
                  {"region_and_whole", region_and_whole(mean, results, o.method == EvalMethod::model)},
                  {"set", set},
                  {"unavailable", unavailable},
                  {"definitions", metric_definitions()}};
  stages.restart_lap();
  if (o.write_report) {
    metrics["stages"] = stages.to_json();  // the report's table: everything up to the report
    write_eval_report(o.out, metrics);
    stages.lap("write report");
  }
  metrics["stages"] = stages.to_json();
  metrics["timings"] = {
      {"compute_ms", compute_ms(stages)}, {"waited_ms", stages.waited_ms()}, {"total_ms", total.ms()}};
  write_file_atomic(o.out / "metrics.json", metrics.dump(2) + "\n");
  return metrics;
}

}  // namespace ii
