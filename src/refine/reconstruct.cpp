#include "refine/reconstruct.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <nanoflann.hpp>

#include "common/error.h"
#include "common/parallel.h"
#include "common/stopwatch.h"
#include "data/photo_points.h"
#include "eval/metrics.h"
#include "io/colmap.h"
#include "io/image.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace ii {

RefineOptions reconstruct_training(const RefineOptions& length) {
  RefineOptions o;
  o.steps = length.steps;
  o.time_budget_s = length.time_budget_s;
  o.position_lr = kGaussianSplattingPositionLr;
  o.position_lr_final = kGaussianSplattingPositionLr / 100;
  o.position_decay_views = 0;
  o.sh_degree = 3;
  o.cover = false;  // densification grows what the points miss, as in 3DGS
  o.hold_out_every = 0;  // held-out views score, never choose
  o.score_at.clear();
  o.densify_every = 100;
  o.densify_from = 1.0 / 60;  // 3DGS: from step 500 of 30,000 ...
  o.densify_until = 0.5;      // ... to 15,000
  o.densify.max_growth = 1e9;  // bounded by ReconstructOptions::max_splats instead
  o.opacity_resets = {0.1, 0.2, 0.3, 0.4};  // 3DGS: every 3,000 steps while densifying
  o.quarter_until = 0.1;
  o.half_until = 0.2;
  return o;
}

RefineOptions reconstruct_training(const std::string& length, int steps) {
  RefineOptions run = steps >= 0 ? RefineOptions{} : refine_setting(length);
  if (steps >= 0) run.steps = steps, run.time_budget_s = 0;
  return reconstruct_training(run);
}

std::vector<PreparedView> working_views(const std::vector<View>& views, int height) {
  std::vector<PreparedView> out(views.size());
  parallel_dynamic(static_cast<int64_t>(views.size()), thread_plan().cores, [&](int64_t i) {
    const View& v = views[static_cast<size_t>(i)];
    PreprocessOptions o;
    o.patch = 1;
    const int w = v.camera.K.width, h = v.camera.K.height;
    // The photos' own size, at most 1600 pixels on the long side (3DGS's limit).
    o.height = height > 0 ? height : std::max(w, h) > 1600 ? static_cast<int>(std::lround(h * 1600.0 / std::max(w, h))) : h;
    out[static_cast<size_t>(i)] = prepare_view(v, o);
  });
  return out;
}

double camera_extent(const std::vector<PreparedView>& views) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const PreparedView& v : views) mean += v.camera.center();
  mean /= std::max<double>(1, views.size());
  double radius = 0;
  for (const PreparedView& v : views) radius = std::max(radius, (v.camera.center() - mean).norm());
  return 1.1 * std::max(radius, 1e-6);
}

namespace {

// Each point's colour: the mean of the working pictures it projects into (no occlusion test: a
// start colour, which the training corrects). Points no view sees in front of it are dropped.
StartPoints coloured(const std::vector<Eigen::Vector3d>& points, const std::vector<PreparedView>& views,
                     std::string source) {
  std::vector<Eigen::Vector3f> sum(points.size(), Eigen::Vector3f::Zero());
  std::vector<int> count(points.size(), 0);
  for (const PreparedView& v : views) {
    const Eigen::Matrix4d w2c = v.camera.w2c_opencv();
    const int w = v.rgb.width;
    for (size_t i = 0; i < points.size(); ++i) {
      const std::optional<PixelOfPoint> p = pixel_of_point(v.camera.K, w2c, points[i]);
      if (!p) continue;
      const float* px = &v.rgb.pixels[(static_cast<size_t>(p->y) * w + p->x) * 3];
      sum[i] += Eigen::Vector3f(px[0], px[1], px[2]);
      ++count[i];
    }
  }
  StartPoints s;
  s.source = std::move(source);
  for (size_t i = 0; i < points.size(); ++i) {
    if (count[i] == 0) continue;
    s.points.push_back(points[i]);
    s.colours.push_back(sum[i] / static_cast<float>(count[i]));
  }
  return s;
}

}  // namespace

StartPoints start_points(const Scene& scene, const std::vector<PreparedView>& views) {
  if (views.size() < 3)
    fail("reconstruct: {} has {} posed view{} to train on; at least 3 are needed", scene.root.string(), views.size(),
         views.size() == 1 ? "" : "s");
  std::vector<Eigen::Vector3d> points = load_scene_points(scene);
  std::string source = "COLMAP's points3D";
  if (points.empty()) {
    std::vector<int> all(scene.views.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    points = triangulate_photo_points(scene, all).points;
    source = "triangulated from the photos";
  }
  if (points.empty())
    fail("reconstruct: no 3D point could be triangulated from the {} views of {}: do the photos overlap?",
         scene.views.size(), scene.root.string());
  StartPoints s = coloured(points, views, source);
  if (s.points.empty())
    fail("reconstruct: none of the {} points of {} ({}) is in any view: are the poses in the points' frame?",
         points.size(), scene.root.string(), source);
  return s;
}

namespace {

// nanoflann's view of the points.
struct PointCloud {
  const std::vector<Eigen::Vector3d>& points;
  size_t kdtree_get_point_count() const { return points.size(); }
  double kdtree_get_pt(size_t i, size_t d) const { return points[i][static_cast<int>(d)]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

}  // namespace

GaussianSet gaussians_from_points(const StartPoints& start) {
  const int64_t n = static_cast<int64_t>(start.points.size());
  const PointCloud cloud{start.points};
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointCloud>, PointCloud, 3>;
  const Tree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  torch::Tensor means = torch::empty({n, 3}), sigma = torch::empty({n}), colours = torch::empty({n, 3});
  float* m = means.data_ptr<float>();
  float* s = sigma.data_ptr<float>();
  float* c = colours.data_ptr<float>();
  parallel_range(n, 1024, thread_plan().cores, [&](int64_t begin, int64_t end) {
   for (int64_t i = begin; i < end; ++i) {
    const Eigen::Vector3d& p = start.points[static_cast<size_t>(i)];
    uint32_t index[4];
    double d2[4];
    const size_t found = tree.knnSearch(p.data(), 4, index, d2);  // the point itself first
    double sum = 0;
    for (size_t k = 1; k < found; ++k) sum += d2[k];
    const double rms = found > 1 ? std::sqrt(sum / (found - 1)) : 0;
    s[i] = static_cast<float>(std::max(rms, 1e-7));
    for (int d = 0; d < 3; ++d) {
      m[i * 3 + d] = static_cast<float>(p[d]);
      c[i * 3 + d] = start.colours[static_cast<size_t>(i)][d];
    }
   }
  });
  // A lone point (no neighbour) takes the median spacing.
  const float median = sigma.median().item<float>();
  sigma.masked_fill_(sigma <= 1e-7f, median > 1e-7f ? median : 1e-2f);
  GaussianSet g;
  g.means = means;
  g.scales = sigma.unsqueeze(1).repeat({1, 3});
  g.quats = torch::tensor({1.f, 0.f, 0.f, 0.f}).repeat({n, 1});
  g.opacities = torch::full({n}, 0.1f);
  g.colors = colours;
  return g;
}

std::vector<ViewScore> score_views(const GaussianSet& gaussians, const std::vector<PreparedView>& views,
                                   const std::array<float, 3>& background, const Lpips* lpips) {
  RenderOptions look;
  look.background = background;
  torch::NoGradGuard no_grad;
  std::vector<ViewScore> scores;
  for (const PreparedView& v : views) {
    const torch::Tensor drawn =
        render(gaussians, {v.camera}, look).rgb.clamp(0, 1).permute({2, 0, 1}).unsqueeze(0).to(torch::kCPU, torch::kFloat32);
    const torch::Tensor truth = image_to_tensor(v.rgb);
    scores.push_back({v.name, psnr(drawn, truth).item<double>(), ssim(drawn, truth).item<double>(), std::nullopt});
    if (lpips) scores.back().lpips = lpips->forward(drawn * 2 - 1, truth * 2 - 1)[0].item<double>();
  }
  return scores;
}

std::string scene_fingerprint(const std::vector<View>& views, int height) {
  // FNV-1a over the height and each view's name, photo size and pose, printed to 9 digits.
  uint64_t h = 1469598103934665603ull;
  auto mix = [&](const std::string& text) {
    for (unsigned char ch : text) h = (h ^ ch) * 1099511628211ull;
  };
  mix(fmt::format("height {}", height));
  for (const View& v : views) {
    mix(v.name);
    mix(fmt::format("{}x{}", v.camera.K.width, v.camera.K.height));
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) mix(fmt::format("{:.9g}", v.camera.c2w(r, c)));
  }
  return fmt::format("{:016x}", h);
}

ReconstructResult reconstruct_scene(const Scene& scene, const ReconstructOptions& options) {
  ReconstructResult r;
  Stopwatch clock;
  const std::vector<PreparedView> training = working_views(scene.views, options.height);
  const std::vector<PreparedView> held = options.eval ? working_views(scene.test_views, options.height)
                                                      : std::vector<PreparedView>{};
  r.prepare_s = clock.lap() / 1000;

  GaussianSet start;
  if (options.start) {
    start = *options.start;
    r.start_source = "given Gaussians";
    r.start_points = start.size();
  } else {
    const StartPoints points = options.points ? *options.points : start_points(scene, training);
    start = gaussians_from_points(points);
    r.start_source = points.source;
    r.start_points = static_cast<int64_t>(points.points.size());
  }
  r.start_s = clock.lap() / 1000;

  std::vector<RefineView> views;
  for (const PreparedView& v : training) {
    RefineView rv;
    rv.name = v.name;
    rv.rgb = v.rgb;
    rv.camera = v.camera;
    rv.may_hold_out = false;
    views.push_back(std::move(rv));
  }
  start = start.to(options.device);
  RefineOptions o = options.training;
  o.extent = camera_extent(training);
  o.densify.max_gaussians = std::max<int64_t>(options.max_splats, start.size());
  r.training = refine_gaussians(start, views, o);
  r.gaussians = r.training.gaussians;
  r.train_s = clock.lap() / 1000;

  const std::vector<PreparedView>& scored = options.eval ? held : training;
  for (const PreparedView& v : held) r.held_out.push_back(v.name);
  r.scores = score_views(r.gaussians, scored, o.background, options.lpips.get());
  const double n = static_cast<double>(r.scores.size());
  for (const ViewScore& s : r.scores) {
    r.mean_psnr += s.psnr / n;
    r.mean_ssim += s.ssim / n;
    if (s.lpips) r.mean_lpips = r.mean_lpips.value_or(0.0) + *s.lpips / n;
  }
  r.score_s = clock.lap() / 1000;
  return r;
}

std::shared_ptr<const Lpips> lpips_scorer(const std::string& vgg_file) {
  const std::optional<std::filesystem::path> given =
      vgg_file.empty() ? std::nullopt : std::optional<std::filesystem::path>(vgg_file);
  if (!lpips_backbone_path(LpipsNet::vgg, given)) return nullptr;
  return std::make_shared<const Lpips>(Lpips::load(LpipsNet::vgg, given));
}

nlohmann::json reconstruct_report(const ReconstructResult& r, const ReconstructOptions& options) {
  nlohmann::json views = nlohmann::json::array();
  for (const ViewScore& s : r.scores) {
    views.push_back({{"view", s.name}, {"psnr", s.psnr}, {"ssim", s.ssim}});
    if (s.lpips) views.back()["lpips"] = *s.lpips;
  }
  nlohmann::json training = refinement_report(r.training, options.training);
  training.erase("losses");
  training["losses_every_100"] = nlohmann::json::array();
  for (size_t i = 0; i < r.training.losses.size(); i += 100) training["losses_every_100"].push_back(r.training.losses[i]);
  return {{"start", {{"source", r.start_source}, {"points", r.start_points}}},
          {"training", training},
          {"splats", r.gaussians.size()},
          {"scored", options.eval ? "held-out views (every 8th)" : "training views"},
          {"held_out", r.held_out},
          {"psnr", r.mean_psnr},
          {"ssim", r.mean_ssim},
          {"lpips", r.mean_lpips ? nlohmann::json(*r.mean_lpips) : nlohmann::json()},
          {"views", views},
          {"seconds", {{"prepare", r.prepare_s}, {"start", r.start_s}, {"train", r.train_s}, {"score", r.score_s}}}};
}

void write_colmap_start(const std::filesystem::path& dir, const std::vector<PreparedView>& views,
                        const StartPoints& start) {
  std::filesystem::create_directories(dir / "images");
  ColmapModel model;
  int id = 1;
  for (const PreparedView& v : views) {
    ColmapCamera camera;
    camera.id = id;
    camera.model = "PINHOLE";
    camera.width = v.rgb.width;
    camera.height = v.rgb.height;
    camera.params = {v.camera.K.fx, v.camera.K.fy, v.camera.K.cx, v.camera.K.cy};
    model.cameras[id] = camera;
    ColmapImage image;
    image.id = id;
    image.camera_id = id;
    image.name = v.name + ".png";
    const Eigen::Matrix4d w2c = v.camera.w2c_opencv();
    const Eigen::Quaterniond q(Eigen::Matrix3d(w2c.topLeftCorner<3, 3>()));
    image.qvec = {q.w(), q.x(), q.y(), q.z()};
    image.tvec = w2c.topRightCorner<3, 1>();
    model.images[id] = image;
    write_png(dir / "images" / image.name, v.rgb);
    ++id;
  }
  for (size_t i = 0; i < start.points.size(); ++i) {
    ColmapPoint p;
    p.id = static_cast<int64_t>(i) + 1;
    p.xyz = start.points[i];
    for (int c = 0; c < 3; ++c)
      p.rgb[static_cast<size_t>(c)] = static_cast<uint8_t>(std::lround(std::clamp(start.colours[i][c], 0.f, 1.f) * 255));
    model.points[p.id] = p;
  }
  write_colmap_model(dir / "sparse" / "0", model, true);
}

}  // namespace ii
