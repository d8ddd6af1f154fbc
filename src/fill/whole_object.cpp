#include "fill/whole_object.h"

#include <algorithm>
#include <deque>
#include <limits>
#include <vector>

#include "render/projection.h"

namespace ii {

namespace {

// A level surface faces up within this (cosine of about 25 degrees).
constexpr double kLevel = 0.9;
// Neighbours of like depth lie less than this share of the depth farther (two balls touching, a
// vase's neck on its body: 3 % split them on the ring rooms) or less than `kNearerStep` nearer: a thin
// part's pixels blend its depth with the wall's behind it (a vase's neck read 0.95 where its cap,
// on it, read 0.70), and a step from them onto the part's wider end is a step nearer.
constexpr double kDepthStep = 0.06;
constexpr double kNearerStep = 0.3;
// What the object stands on spans at least this many times the part's width across the picture.
constexpr double kReachesOut = 2.5;
// Fewer level pixels than this under the part: nothing it stands on is in view.
constexpr int64_t kMinSupport = 20;

int64_t cell_key(int64_t a, int64_t b) { return a * 1000003 + b; }

// The pixels reached from `seed` through 4-neighbours that are `covered`, of like depth and higher
// than `above`; one flag per pixel.
std::vector<uint8_t> grown_above(const torch::Tensor& depth, const torch::Tensor& covered, const torch::Tensor& seed,
                                 const torch::Tensor& height, double above) {
  const int64_t h = depth.size(0), w = depth.size(1);
  const double* d = depth.data_ptr<double>();
  const double* ht = height.data_ptr<double>();
  const bool* ok = covered.data_ptr<bool>();
  const bool* start = seed.data_ptr<bool>();
  std::vector<uint8_t> in(static_cast<size_t>(h * w), 0);
  std::deque<int64_t> queue;
  for (int64_t i = 0; i < h * w; ++i)
    if (start[i]) in[static_cast<size_t>(i)] = 1, queue.push_back(i);
  while (!queue.empty()) {
    const int64_t i = queue.front();
    queue.pop_front();
    const int64_t y = i / w, x = i % w;
    const int64_t next[4] = {x > 0 ? i - 1 : -1, x + 1 < w ? i + 1 : -1, y > 0 ? i - w : -1, y + 1 < h ? i + w : -1};
    for (int64_t j : next) {
      if (j < 0 || in[static_cast<size_t>(j)] || !ok[j] || ht[j] <= above) continue;
      if (d[j] > (1 + kDepthStep) * d[i] || d[j] < (1 - kNearerStep) * d[i]) continue;
      in[static_cast<size_t>(j)] = 1;
      queue.push_back(j);
    }
  }
  return in;
}

// Up to kColourSamples colours of `picture` where `where` (H W, bool) holds, evenly spaced.
constexpr int64_t kColourSamples = 256;
std::vector<Eigen::Vector3f> colour_samples(const Image& picture, const torch::Tensor& where) {
  const torch::Tensor pixels = where.reshape({-1}).nonzero().squeeze(1).contiguous();
  std::vector<Eigen::Vector3f> out;
  const int64_t n = pixels.numel(), step = std::max<int64_t>(1, n / kColourSamples);
  const int64_t* p = pixels.data_ptr<int64_t>();
  for (int64_t k = 0; k < n; k += step) {
    const size_t i = static_cast<size_t>(p[k]) * static_cast<size_t>(picture.channels);
    out.emplace_back(picture.pixels[i], picture.pixels[i + 1], picture.pixels[i + 2]);
  }
  return out;
}

// From the 10th to the 90th percentile of `values`, each end moved out by `by`.
std::pair<double, double> widened(const torch::Tensor& values, double by) {
  return {torch::quantile(values, 0.1).item<double>() - by, torch::quantile(values, 0.9).item<double>() + by};
}

// The object's outline seen from above: the cells of a 24th of its size that its visible points
// fall in and, behind those in its front half, as far as half the object is wide (its hidden back,
// for an object about as deep as it is wide: a ball's front reaches back over its hidden half, a
// box's top does not reach past its back), seen from `eye`.
void add_footprint(ObjectAboveSupport& object, const torch::Tensor& points, double size, double wide) {
  object.across = object.up.unitOrthogonal();
  object.along = object.up.cross(object.across);
  object.cell = std::max(1e-9, size / 24);
  const int steps = static_cast<int>(std::ceil(0.5 * wide / object.cell));
  const double* p = points.data_ptr<double>();
  std::vector<Eigen::Vector3d> away(static_cast<size_t>(points.size(0)));  // from the eye along the plane
  double front = std::numeric_limits<double>::infinity();
  for (int64_t i = 0; i < points.size(0); ++i) {
    Eigen::Vector3d& a = away[static_cast<size_t>(i)];
    a = Eigen::Vector3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]) - object.eye;
    a -= a.dot(object.up) * object.up;
    front = std::min(front, a.norm());
  }
  for (int64_t i = 0; i < points.size(0); ++i) {
    const Eigen::Vector3d q(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    const Eigen::Vector3d& a = away[static_cast<size_t>(i)];
    const Eigen::Vector3d step = a.norm() > 0 ? Eigen::Vector3d(a * (object.cell / a.norm())) : Eigen::Vector3d::Zero();
    const int behind = a.norm() <= front + 0.5 * wide ? steps : 0;
    for (int k = 0; k <= behind; ++k) {
      const Eigen::Vector3d r = q + k * step;
      const auto ca = static_cast<int64_t>(std::floor(r.dot(object.across) / object.cell));
      const auto cb = static_cast<int64_t>(std::floor(r.dot(object.along) / object.cell));
      for (int64_t da = -1; da <= 1; ++da)
        for (int64_t db = -1; db <= 1; ++db) object.footprint.insert(cell_key(ca + da, cb + db));
    }
  }
}

}  // namespace

bool ObjectAboveSupport::within_reach(const Eigen::Vector3d& p, double camera_depth) const {
  Eigen::Vector3d away = p - eye;
  away -= away.dot(up) * up;
  const double r = away.norm();
  return (r >= reach.first && r <= reach.second) || (camera_depth >= depths.first && camera_depth <= depths.second);
}

bool ObjectAboveSupport::coloured_like_it(const Eigen::Vector3f& colour) const {
  auto nearest = [&](const std::vector<Eigen::Vector3f>& samples) {
    float best = std::numeric_limits<float>::infinity();
    for (const Eigen::Vector3f& c : samples) best = std::min(best, (c - colour).squaredNorm());
    return best;
  };
  return nearest(object_colours) < nearest(surface_colours);
}

bool ObjectAboveSupport::under(const Eigen::Vector3d& p) const {
  const double height = p.dot(up);
  if (height > above || height < deepest) return false;
  return footprint.count(cell_key(static_cast<int64_t>(std::floor(p.dot(across) / cell)),
                                  static_cast<int64_t>(std::floor(p.dot(along) / cell)))) > 0;
}

namespace {

// The value at rank q (n - 1) of `t`, rounded down.
double quantile_at(const torch::Tensor& t, double q) {
  return torch::quantile(t, q, c10::nullopt, false, "lower").item<double>();
}

// Each pixel of a render with its depth, in the scene: where it lies, how high along up, how far
// from the camera along the level plane (an object's cap and foot alike), whether it is level.
struct PixelsInScene {
  torch::Tensor points;  // (H W, 3)
  torch::Tensor height, reach, level;  // (H, W)
};
PixelsInScene pixels_in_scene(const Camera& camera, const torch::Tensor& depth, const torch::Tensor& covered,
                              const Eigen::Vector3d& up) {
  const int64_t h = depth.size(0), w = depth.size(1);
  const torch::Tensor upt = torch::tensor({up.x(), up.y(), up.z()}, torch::kFloat64);
  const torch::Tensor grid = depth_points(camera, depth);  // (H, W, 3)
  PixelsInScene s;
  s.points = grid.reshape({-1, 3});
  s.height = (s.points * upt).sum(1).reshape({h, w}).contiguous();
  const Eigen::Vector3d eye = camera.center();
  const torch::Tensor from_eye = s.points - torch::tensor({eye.x(), eye.y(), eye.z()}, torch::kFloat64);
  s.reach = (from_eye - (from_eye * upt).sum(1, true) * upt).norm(2, 1).reshape({h, w});
  s.level = (point_normals(camera, grid) * upt).sum(2).gt(kLevel).logical_and(covered);
  return s;
}

// What a part stands on: its height, the bin its heights were taken in, its pixels (H W, bool).
struct Support {
  double height = 0, bin = 0;
  torch::Tensor pixels;
};

// The highest level surface near the part and under its foot that shows at least half as many
// pixels as the part and reaches out beyond it on the picture (a table, a floor; a ball's level
// top under the part, part of the object, does not), its heights in bins of 3 % of the part's
// distance `scale` (a trained floor's surface is that rough on the ring rooms: at 1 % no bin held
// enough).
std::optional<Support> support_under(const Camera& camera, const Eigen::Vector3d& up, const PixelsInScene& scene,
                                     const torch::Tensor& part, double scale) {
  const int64_t h = part.size(0), w = part.size(1);
  // Up on the picture (x right, y down) and across it: a photo can be taken on its side.
  const Eigen::Vector3d up_in_camera = camera.rotation().transpose() * up;  // OpenGL axes
  const Eigen::Vector2d across = Eigen::Vector2d(up_in_camera.y(), up_in_camera.x()).normalized();
  const bool sideways = std::abs(up_in_camera.x()) > std::abs(up_in_camera.y());
  const torch::Tensor part_heights = scene.height.index({part});
  const double low = quantile_at(part_heights, 0.02);
  const double extent = std::max(1e-9, quantile_at(part_heights, 0.98) - low);
  // Near the part: its box grown by its size on every side, by a sixth of the picture at least, and
  // downwards by half of it (a click on a patterned body grows over a speck, its foot far below).
  const torch::Tensor where = part.nonzero();
  const int64_t y0 = where.select(1, 0).min().item<int64_t>(), y1 = where.select(1, 0).max().item<int64_t>();
  const int64_t x0 = where.select(1, 1).min().item<int64_t>(), x1 = where.select(1, 1).max().item<int64_t>();
  const int64_t gy = std::max(y1 - y0 + 2, h / 6), gx = std::max(x1 - x0 + 2, h / 6);
  int64_t top = y0 - gy, bottom = y1 + gy, left = x0 - gx, right = x1 + gx;
  const int64_t down = h / 2;
  if (!sideways) (up_in_camera.y() > 0 ? bottom : top) += up_in_camera.y() > 0 ? down : -down;
  else (up_in_camera.x() > 0 ? left : right) += up_in_camera.x() > 0 ? -down : down;
  torch::Tensor near = torch::zeros({h, w}, torch::kBool);
  near.slice(0, std::max<int64_t>(0, top), std::min(h, bottom + 1))
      .slice(1, std::max<int64_t>(0, left), std::min(w, right + 1))
      .fill_(true);
  // How far a set of pixels spans across the picture (along `across`).
  auto span = [&](const torch::Tensor& rows, const torch::Tensor& columns) {
    const torch::Tensor t = columns.to(torch::kFloat64) * across.x() + rows.to(torch::kFloat64) * across.y();
    return (t.max() - t.min()).item<double>() + 1;
  };
  const double part_span = span(where.select(1, 0), where.select(1, 1));
  const torch::Tensor under = scene.level.logical_and(near).logical_and(part.logical_not())
                                  .logical_and(scene.height.le(low + 0.1 * extent));
  const torch::Tensor levels = scene.height.index({under});
  const int64_t needed =  // a big part (a cup filling the view) stands on what shows a hundredth of it
      std::max<int64_t>(kMinSupport, std::min(part_heights.numel() / 2, h * w / 100));
  if (levels.numel() < needed) return std::nullopt;
  const double bin = 0.03 * scale;
  const torch::Tensor bins = torch::floor(levels / bin).to(torch::kInt64);
  const int64_t first = bins.min().item<int64_t>();
  const torch::Tensor counts = torch::bincount(bins - first);
  const torch::Tensor neighbourhood =  // each bin with its two neighbours: a level surface spans a few
      counts + torch::cat({counts.slice(0, 1), torch::zeros({1}, counts.options())}) +
      torch::cat({torch::zeros({1}, counts.options()), counts.slice(0, 0, -1)});
  const torch::Tensor big = neighbourhood.ge(needed).nonzero().squeeze(1);
  const torch::Tensor level_pixels = under.reshape({-1}).nonzero().squeeze(1);
  for (int64_t k = big.numel() - 1; k >= 0; --k) {
    const torch::Tensor on_it = (bins - first - big[k]).abs().le(1);
    const torch::Tensor pixels = level_pixels.index({on_it});
    if (span(pixels.div(w, "floor"), pixels.remainder(w)) < kReachesOut * part_span) continue;
    Support support;
    support.height = levels.index({on_it}).median().item<double>();
    support.bin = bin;
    support.pixels = torch::zeros({h * w}, torch::kBool);
    support.pixels.index_put_({level_pixels.index({on_it})}, true);
    return support;
  }
  return std::nullopt;
}

}  // namespace

std::optional<ObjectAboveSupport> object_above_support(const Camera& camera, const Image& picture,
                                                       const torch::Tensor& depth_in,
                                                       const torch::Tensor& covered_in, const torch::Tensor& part_in,
                                                       const Eigen::Vector3d& up_in) {
  const int64_t h = depth_in.size(0), w = depth_in.size(1);
  const torch::Tensor depth = depth_in.to(torch::kCPU, torch::kFloat64).contiguous();
  const torch::Tensor covered = covered_in.to(torch::kCPU, torch::kBool).contiguous();
  const torch::Tensor part = part_in.to(torch::kCPU, torch::kBool).logical_and(covered).contiguous();
  if (!part.any().item<bool>()) return std::nullopt;
  const Eigen::Vector3d up = up_in.normalized();
  const PixelsInScene scene = pixels_in_scene(camera, depth, covered, up);
  const double scale = depth.index({part}).median().item<double>();  // how far the part is
  const std::optional<Support> support = support_under(camera, up, scene, part, scale);
  if (!support) return std::nullopt;

  // Grown from the part over neighbours of like depth above the surface.
  const double above = support->height + 0.5 * support->bin;
  const std::vector<uint8_t> in = grown_above(depth, covered, part, scene.height, above);
  const int64_t count = std::count(in.begin(), in.end(), uint8_t{1});
  if (2 * count > covered.sum().item<int64_t>()) return std::nullopt;
  const torch::Tensor grown = torch::from_blob(const_cast<uint8_t*>(in.data()), {h, w}, torch::kUInt8).to(torch::kBool);
  ObjectAboveSupport out;
  out.mask = Image(static_cast<int>(w), static_cast<int>(h), 1);
  for (int64_t i = 0; i < h * w; ++i) out.mask.pixels[static_cast<size_t>(i)] = in[static_cast<size_t>(i)] ? 1.f : 0.f;
  out.up = up;
  out.above = above;
  // The surface's own splats under the object down to as deep as its roughness (a trained file
  // gives the object's colours there; deeper lies the table's side, a pedestal's faces).
  out.deepest = support->height - 2.5 * support->bin;
  out.eye = camera.center();

  // The object's reach: its camera depths or its distances from the camera along the level
  // surface, as the part's widened by the object's size (a vase's foot seen from above lies behind
  // its cap in depth by more than the cap is wide, not along the surface; a pot's rim seen from the
  // side lies behind its front in both). From the part: a translucent file's edges ramp down to
  // the wall behind it in small steps of depth, and the growth can run on to the wall. The size:
  // that of what of the object lies within the part's own size of it.
  const torch::Tensor part_reach = scene.reach.index({part}), part_depths = depth.index({part});
  auto size_of = [&](const torch::Tensor& pixels) {  // across and up the view, and in height
    if (pixels.size(0) == 0) return 0.0;
    const torch::Tensor rows = pixels.select(1, 0), columns = pixels.select(1, 1);
    const torch::Tensor heights = scene.height.index({rows, columns});
    return std::max({static_cast<double>((columns.max() - columns.min()).item<int64_t>()) * scale / camera.K.fx,
                     static_cast<double>((rows.max() - rows.min()).item<int64_t>()) * scale / camera.K.fy,
                     quantile_at(heights, 0.98) - quantile_at(heights, 0.02)});
  };
  auto within = [&](double size) {
    out.depths = widened(part_depths, size);
    out.reach = widened(part_reach, size);
    return scene.reach.ge(out.reach.first).logical_and(scene.reach.le(out.reach.second))
        .logical_or(depth.ge(out.depths.first).logical_and(depth.le(out.depths.second)));
  };
  const double part_size = size_of(part.nonzero());
  const double size = std::max(part_size, size_of(grown.logical_and(within(part_size)).nonzero()));
  const torch::Tensor object = grown.logical_and(within(size));

  out.object_colours = colour_samples(picture, object);
  out.surface_colours = colour_samples(picture, support->pixels);
  const torch::Tensor pixels = object.nonzero();
  if (pixels.size(0) > 0)
    add_footprint(out, scene.points.reshape({h, w, 3}).index({pixels.select(1, 0), pixels.select(1, 1)}).contiguous(),
                  size, size_of(pixels));
  return out;
}

}  // namespace ii
