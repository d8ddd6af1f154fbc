#include "fill/cameras.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>

#include "common/error.h"
#include "common/torch.h"
#include "data/preprocess.h"
#include "geometry/visibility.h"
#include "render/projection.h"
#include "render/rasterizer.h"

namespace ii {

namespace {

constexpr int kScoreHeight = 64;  // the small renders that score a camera

// The region's share of the camera's pixels; `sights` (optional) keeps what the camera saw, whole
// inside `window` (the one its splats were culled to) alone.
double region_share(const GaussianSet& weights, const Camera& camera, std::vector<Sight>* sights = nullptr,
                    const std::optional<PixelWindow>& window = std::nullopt) {
  RenderOptions black;
  black.background = {0.f, 0.f, 0.f};
  const RenderOutput out = render(weights, {camera}, black);
  if (sights) {
    torch::Tensor complete;
    if (window) {
      const auto rows = torch::arange(camera.K.height, torch::kFloat32).unsqueeze(1) + 0.5f;
      const auto cols = torch::arange(camera.K.width, torch::kFloat32).unsqueeze(0) + 0.5f;
      complete = (rows >= window->y0).logical_and(rows <= window->y1).logical_and(cols >= window->x0)
                     .logical_and(cols <= window->x1);
    }
    sights->push_back({camera, out.depth.squeeze(2).to(torch::kCPU).contiguous(),
                       out.alpha.squeeze(2).to(torch::kCPU).contiguous(), complete, {}, {},
                       out.rgb.select(2, 0).to(torch::kCPU).contiguous()});
  }
  return out.rgb.select(2, 0).mean().item<double>();
}

Camera small(const Camera& camera) {
  const int h = kScoreHeight, w = std::max(8, camera.K.width * kScoreHeight / std::max(1, camera.K.height));
  return camera.resized(w, h);
}

struct Sphere {
  Eigen::Vector3d centre;
  double radius;
};
Sphere region_sphere(const GaussianSet& scene, const torch::Tensor& in_region) {
  const torch::Tensor m = scene.means.index({in_region}).to(torch::kFloat64);
  const torch::Tensor lo = std::get<0>(m.min(0)), hi = std::get<0>(m.max(0));
  const torch::Tensor c = (lo + hi) / 2;
  Sphere s;
  s.centre = {c[0].item<double>(), c[1].item<double>(), c[2].item<double>()};
  s.radius = std::max(1e-6, ((hi - lo) / 2).norm().item<double>());
  return s;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
}

// The reference (best score) and the best others at least `min_apart` degrees from every
// chosen one (seen from `centre`), within `max_from_reference` of the reference.
std::vector<size_t> pick_views(const std::vector<double>& score, const std::vector<Camera>& cameras,
                               const Eigen::Vector3d& centre, int views, double min_apart, double max_from_reference) {
  std::vector<size_t> order(score.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return score[a] > score[b]; });
  std::vector<size_t> chosen;
  for (size_t i : order) {
    if (score[i] <= 0 || static_cast<int>(chosen.size()) == views) break;
    const Eigen::Vector3d dir = cameras[i].center() - centre;
    bool ok = chosen.empty() || angle_deg(dir, cameras[chosen[0]].center() - centre) <= max_from_reference;
    for (size_t j : chosen) ok = ok && angle_deg(dir, cameras[j].center() - centre) >= min_apart;
    if (ok) chosen.push_back(i);
  }
  // Too few far enough apart: the next best ones, however close.
  for (size_t i : order)
    if (static_cast<int>(chosen.size()) < views && score[i] > 0 &&
        std::find(chosen.begin(), chosen.end(), i) == chosen.end())
      chosen.push_back(i);
  return chosen;
}

// Each sight's surface without the region (`kept`, drawn near the region as the sight was), and
// where it was seen: outside the region's pixels, or behind them on another sight's surface, that
// sight looking at it from the same side (a thin wall's inside, seen through a hole, is not its
// outside that another camera saw).
void add_kept_surfaces(std::vector<Sight>& sights, const std::vector<GaussianSet>& kept) {
  std::vector<SeenDepth> surfaces;  // each sight's whole surface, once
  for (const Sight& s : sights) surfaces.push_back({s.camera, s.depth, drawn_whole(s)});
  for (size_t i = 0; i < sights.size(); ++i) {
    Sight& s = sights[i];
    const RenderOutput k = render(kept[i], {s.camera});
    s.kept_depth = k.depth.squeeze(2).to(torch::kCPU).contiguous();
    const torch::Tensor drawn = k.alpha.squeeze(2).to(torch::kCPU) > 0.5;
    const torch::Tensor behind = (s.share > 0.1).logical_and(drawn);
    s.kept_seen = drawn.logical_and(behind.logical_not());
    const torch::Tensor pixels = behind.nonzero();
    if (pixels.size(0) == 0) continue;
    const torch::Tensor rows = pixels.select(1, 0), cols = pixels.select(1, 1);
    const torch::Tensor world = unproject(s.camera, rows.to(torch::kFloat64), cols.to(torch::kFloat64),
                                          s.kept_depth.index({rows, cols}).to(torch::kFloat64));
    const torch::Tensor normals = depth_normals(s.camera, s.kept_depth).index({rows, cols});
    torch::Tensor seen = torch::zeros({pixels.size(0)}, torch::kBool);
    for (size_t j = 0; j < sights.size(); ++j) {
      if (j == i) continue;
      const Eigen::Vector3d c = sights[j].camera.center();
      const torch::Tensor to_j = torch::tensor({c.x(), c.y(), c.z()}, torch::kFloat64) - world;
      const torch::Tensor facing = (to_j * normals).sum(1) > 0.1 * to_j.norm(2, 1);
      seen.logical_or_(facing.logical_and(on_seen_surface(world, surfaces[j], kSeenTolerance)));
    }
    s.kept_seen.index_put_({rows, cols}, seen);
  }
}

// The widest angle between two sights' directions from `centre`, in degrees.
double sights_spread_deg(const std::vector<Sight>& sights, const Eigen::Vector3d& centre) {
  double widest = 0;
  for (size_t i = 0; i < sights.size(); ++i)
    for (size_t j = i + 1; j < sights.size(); ++j)
      widest = std::max(widest, angle_deg(sights[i].camera.center() - centre, sights[j].camera.center() - centre));
  return widest;
}

// Cameras this far apart round the region see behind it from other sides.
constexpr double kRoundDeg = 90;

// Whether `point` is in front of `camera` and inside its picture.
bool in_picture(const Camera& camera, const Eigen::Vector3d& point) {
  const Eigen::Vector3d p = (camera.w2c_opencv() * point.homogeneous()).head<3>();
  if (p.z() <= 0) return false;
  const double u = camera.K.fx * p.x() / p.z() + camera.K.cx, v = camera.K.fy * p.y() / p.z() + camera.K.cy;
  return u >= 0 && v >= 0 && u < camera.K.width && v < camera.K.height;
}

// At most this many cameras, the nearest to the region, are scored for the choice.
constexpr size_t kCandidates = 16;

// Of the cameras that see the region's centre beyond `near` (the nearest, scored), up to
// kCandidates more that look at it from directions at least 10 degrees from all those taken,
// the farthest from them first: on a capture all round its object the nearest lie on one side.
std::vector<size_t> other_sides(const std::vector<NamedCamera>& given, const std::vector<size_t>& near,
                                const Eigen::Vector3d& centre) {
  constexpr double kApartDeg = 10;
  std::vector<Eigen::Vector3d> taken;
  for (size_t i : near) taken.push_back(given[i].camera.center() - centre);
  std::vector<size_t> out;
  while (out.size() < kCandidates) {
    size_t best = given.size();
    double best_apart = kApartDeg;
    for (size_t i = 0; i < given.size(); ++i) {
      const Camera& c = given[i].camera;
      if (!in_picture(c, centre)) continue;
      double apart = 180;
      for (const Eigen::Vector3d& t : taken) apart = std::min(apart, angle_deg(c.center() - centre, t));
      if (apart > best_apart) {
        best_apart = apart;
        best = i;
      }
    }
    if (best == given.size()) break;
    out.push_back(best);
    taken.push_back(given[best].camera.center() - centre);
  }
  return out;
}

Camera working_camera(const Camera& camera, int height) {
  PreprocessOptions p;
  p.height = height;
  return working_size(camera.K.width, camera.K.height, p).working_camera(camera);
}

// The 8 best-scoring cameras besides `chosen` that see the region, at the working height.
std::vector<NamedCamera> observers_besides(const std::vector<size_t>& chosen, const std::vector<double>& score,
                                           const std::function<NamedCamera(size_t)>& camera, int height) {
  std::vector<size_t> order(score.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return score[a] > score[b]; });
  std::vector<NamedCamera> out;
  for (size_t i : order) {
    if (score[i] <= 0 || out.size() == 8) break;
    if (std::find(chosen.begin(), chosen.end(), i) != chosen.end()) continue;
    NamedCamera c = camera(i);
    c.camera = working_camera(c.camera, height);
    out.push_back(std::move(c));
  }
  return out;
}


}  // namespace

torch::Tensor drawn_whole(const Sight& sight) {
  const torch::Tensor drawn = sight.alpha > 0.5;
  return sight.complete.defined() ? drawn.logical_and(sight.complete) : drawn;
}

torch::Tensor region_flags(const RegionMask& region, const torch::Device& device) {
  std::vector<uint8_t> flags(region.begin(), region.end());
  return torch::from_blob(flags.data(), {static_cast<int64_t>(flags.size())}, torch::kUInt8).to(torch::kBool).to(device);
}

std::optional<PixelWindow> region_window(const GaussianSet& region, const Camera& camera) {
  const std::optional<PixelWindow> covered = covered_window(region, camera, 0);
  if (!covered) return std::nullopt;
  // grown by a tenth of its size and 4 pixels
  return covered_window(region, camera, 4 + 0.1 * std::max(covered->x1 - covered->x0, covered->y1 - covered->y0));
}

torch::Tensor near_region(const GaussianSet& set, const GaussianSet& region, const Camera& camera) {
  const std::optional<PixelWindow> window = region_window(region, camera);
  if (!window) return torch::ones({set.size()}, torch::TensorOptions().dtype(torch::kBool).device(set.means.device()));
  return reaching_window(set, camera, *window);
}

GaussianSet region_weight_set(const GaussianSet& scene, const torch::Tensor& in_region) {
  GaussianSet g = scene;
  g.colors = in_region.to(torch::kFloat32).unsqueeze(1).expand({scene.size(), 3}).contiguous();
  g.sh_degree = -1;
  return g;
}

ChosenCameras choose_given_cameras(const GaussianSet& scene, const RegionMask& region,
                                   const std::vector<NamedCamera>& given, const FillCameraOptions& options,
                                   StageTimes* stages) {
  torch::NoGradGuard no_grad;
  StageTimes unrecorded;
  StageTimes& times = stages ? *stages : unrecorded;
  const torch::Tensor in_region = region_flags(region, scene.means.device());
  const Sphere sphere = region_sphere(scene, in_region);
  // Those the region's centre is in front of and inside, nearest first; the 16 nearest are rendered.
  std::vector<size_t> candidates;
  for (size_t i = 0; i < given.size(); ++i)
    if (in_picture(given[i].camera, sphere.centre)) candidates.push_back(i);
  std::stable_sort(candidates.begin(), candidates.end(), [&](size_t a, size_t b) {
    return (given[a].camera.center() - sphere.centre).norm() < (given[b].camera.center() - sphere.centre).norm();
  });
  if (candidates.size() > kCandidates) candidates.resize(kCandidates);
  const GaussianSet weights = region_weight_set(scene, in_region), region_set = select_rows(scene, in_region);
  times.lap("choose cameras: the region's set");
  // The small renders are read near the region alone (the share, and what the hole test asks
  // of the sights): each draws only the splats that reach it there.
  std::vector<torch::Tensor> drawn_rows;  // each sight's rows (culled to its window, else all)
  auto share = [&](const Camera& camera, std::vector<Sight>* keep) {
    const std::optional<PixelWindow> window = options.cull ? region_window(region_set, camera) : std::nullopt;
    const torch::Tensor rows =
        window ? reaching_window(weights, camera, *window)
               : torch::ones({weights.size()}, torch::TensorOptions(torch::kBool).device(weights.means.device()));
    const GaussianSet near = window ? select_rows(weights, rows) : weights;
    times.lap("choose cameras: culling");
    const double s = region_share(near, camera, keep, window);
    if (keep) drawn_rows.push_back(rows);
    times.lap("choose cameras: scoring renders");
    return s;
  };
  std::vector<double> score(given.size(), 0.0);
  std::vector<Camera> cameras;
  for (const NamedCamera& c : given) cameras.push_back(c.camera);
  std::vector<Sight> sights;
  for (size_t i : candidates) score[i] = share(small(given[i].camera), &sights);
  // Cameras from other sides see more (a capture all round its object): their renders join the
  // sights, not the choice.
  for (size_t i : other_sides(given, candidates, sphere.centre)) share(small(given[i].camera), &sights);
  // Only a capture that goes round the region sees behind it from other sides: the surfaces
  // behind the region are worth their renders there alone (0.8 s of a 665 k-splat fill).
  const bool round = sights_spread_deg(sights, sphere.centre) >= kRoundDeg;
  if (round) {
    std::vector<GaussianSet> kept;  // each sight's splats without the region
    for (const torch::Tensor& rows : drawn_rows) kept.push_back(select_rows(weights, rows.logical_and(in_region.logical_not())));
    add_kept_surfaces(sights, kept);
    times.lap("choose cameras: the surfaces behind the region");
  }
  if (!options.reference.empty()) {
    const auto named = std::find_if(given.begin(), given.end(), [&](const NamedCamera& c) { return c.name == options.reference; });
    if (named == given.end()) fail("--reference-view {}: no camera of that name", options.reference);
    const size_t r = static_cast<size_t>(named - given.begin());
    if (score[r] <= 0) score[r] = share(small(given[r].camera), nullptr);
    if (score[r] <= 0) fail("--reference-view {}: that camera does not see the region", options.reference);
    score[r] = 2;  // first
  }
  const std::vector<size_t> chosen = pick_views(score, cameras, sphere.centre, options.views, 8, 90);
  if (chosen.empty())
    fail("none of the {} cameras sees the region (its centre ({:.4g}, {:.4g}, {:.4g}) is outside every view, or "
         "hidden): give cameras that see it, or none (automatic views)",
         given.size(), sphere.centre.x(), sphere.centre.y(), sphere.centre.z());
  ChosenCameras out;
  for (size_t i : chosen) {
    out.cameras.push_back({given[i].name, working_camera(given[i].camera, options.height)});
    out.visible.push_back(std::min(1.0, score[i]));
  }
  out.observers = observers_besides(chosen, score, [&](size_t i) { return given[i]; }, options.height);
  out.sights = std::move(sights);
  out.captured = true;
  out.round = round;
  out.how = fmt::format("given: {} of {} cameras see the region's centre, the {} that see most of it{}", candidates.size(),
                        given.size(), chosen.size(), round ? "; they go round it" : "");
  return out;
}

Eigen::Vector3d guess_up(const SplatCloud& cloud, const RegionMask& region) {
  const auto [lo, hi] = splat_bounds(cloud);
  int axis = 0;
  (hi - lo).minCoeff(&axis);
  const auto [rlo, rhi] = splat_bounds(cloud, &region);
  const double centre = (rlo[axis] + rhi[axis]) / 2;
  size_t below = 0, above = 0;
  for (size_t i = 0; i < cloud.size(); ++i)
    if (!region[i]) (cloud.means[3 * i + static_cast<size_t>(axis)] < centre ? below : above) += 1;
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  up[axis] = below >= above ? 1 : -1;
  return up;
}

ChosenCameras choose_automatic_cameras(const GaussianSet& scene, const RegionMask& region,
                                       const FillCameraOptions& options, StageTimes* stages) {
  torch::NoGradGuard no_grad;
  StageTimes unrecorded;
  StageTimes& times = stages ? *stages : unrecorded;
  const torch::Tensor in_region = region_flags(region, scene.means.device());
  const Sphere sphere = region_sphere(scene, in_region);
  Eigen::Vector3d up = options.up.norm() > 0 ? options.up.normalized() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d side = (std::abs(up.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).cross(up).normalized();
  const Eigen::Vector3d front = up.cross(side);
  // Only what lies within reach of the farthest camera can stand between a camera and the region.
  const double reach = 7 * sphere.radius + sphere.radius;
  const torch::Tensor centre = torch::tensor({sphere.centre.x(), sphere.centre.y(), sphere.centre.z()})
                                   .to(scene.means.device(), torch::kFloat32);
  const torch::Tensor near = (scene.means - centre).norm(2, 1) <= reach;
  const GaussianSet weights = region_weight_set(select_rows(scene, near), in_region.index({near}));
  times.lap("choose cameras: the region's set");
  const int height = options.height, width = std::max(8, height * 4 / 3 / 8 * 8);
  const Intrinsics K = Intrinsics::from_fov(width, height, 2 * std::atan(std::tan(25 * M_PI / 180) * width / height),
                                            50 * M_PI / 180);
  std::vector<Camera> cameras;
  std::vector<double> score;
  std::vector<Sight> sights;
  for (double distance : {4.0, 7.0})
    for (double elevation : {10.0, 30.0, 50.0})
      for (int azimuth = 0; azimuth < 360; azimuth += 30) {
        const double a = azimuth * M_PI / 180, e = elevation * M_PI / 180;
        const Eigen::Vector3d dir = std::cos(e) * (std::cos(a) * front + std::sin(a) * side) + std::sin(e) * up;
        Camera c;
        c.K = K;
        c.c2w = look_at(sphere.centre + distance * sphere.radius * dir, sphere.centre, up);
        cameras.push_back(c);
        score.push_back(region_share(weights, small(c), &sights) * (distance == 4.0 ? 1.0 : 0.999));
        times.lap("choose cameras: scoring renders");
      }
  const std::vector<size_t> chosen = pick_views(score, cameras, sphere.centre, options.views, 12, 60);
  if (chosen.empty())
    fail("no automatic camera sees the region (centre ({:.4g}, {:.4g}, {:.4g}), radius {:.4g}): every view of it is "
         "hidden by other splats; give cameras (--scene or --cameras)",
         sphere.centre.x(), sphere.centre.y(), sphere.centre.z(), sphere.radius);
  ChosenCameras out;
  auto named = [&](size_t i) { return NamedCamera{fmt::format("auto_{:02d}", i), cameras[i]}; };
  for (size_t i : chosen) {
    out.cameras.push_back(named(i));
    out.visible.push_back(score[i]);
  }
  out.observers = observers_besides(chosen, score, named, options.height);
  out.sights = std::move(sights);
  out.how = fmt::format(
      "automatic: {} cameras on rings around the region (up ({:.3g}, {:.3g}, {:.3g})), the {} that see most of it",
      cameras.size(), up.x(), up.y(), up.z(), chosen.size());
  return out;
}

}  // namespace ii
