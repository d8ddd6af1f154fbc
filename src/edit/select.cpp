#include "edit/select.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <numeric>

#include "common/error.h"
#include "common/parallel.h"
#include "edit/mask_shapes.h"

namespace ii {

namespace {

// The points in cubes of `side`: cells sorted by a packed key, each point's cell found by bisection.
class PointGrid {
 public:
  PointGrid(const std::vector<Eigen::Vector3d>& points, double side) : side_(side) {
    order_.resize(points.size());
    std::iota(order_.begin(), order_.end(), 0);
    keys_.resize(points.size());
    for (size_t i = 0; i < points.size(); ++i) keys_[i] = key_of(cell_of(points[i]));
    std::sort(order_.begin(), order_.end(), [&](size_t a, size_t b) { return keys_[a] < keys_[b]; });
    sorted_keys_.resize(order_.size());
    for (size_t i = 0; i < order_.size(); ++i) sorted_keys_[i] = keys_[order_[i]];
  }
  // fn(j) for every point in the 27 cells around `p`: nine runs of three cells (z varies fastest
  // in the key: three neighbours along z are one range of the sorted keys).
  template <typename Fn>
  void around(const Eigen::Vector3d& p, Fn&& fn) const {
    const Eigen::Vector3i c = cell_of(p);
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const auto lo = std::lower_bound(sorted_keys_.begin(), sorted_keys_.end(), key_of(c + Eigen::Vector3i(dx, dy, -1)));
        const auto hi = std::upper_bound(lo, sorted_keys_.end(), key_of(c + Eigen::Vector3i(dx, dy, 1)));
        for (auto it = lo; it != hi; ++it) fn(order_[static_cast<size_t>(it - sorted_keys_.begin())]);
      }
  }

 private:
  static constexpr int kBits = 21, kLimit = (1 << (kBits - 1)) - 2;
  Eigen::Vector3i cell_of(const Eigen::Vector3d& p) const {
    Eigen::Vector3i c;
    for (int a = 0; a < 3; ++a) {
      const double v = std::floor(p[a] / side_);
      c[a] = std::isfinite(v) ? static_cast<int>(std::clamp(v, -double(kLimit), double(kLimit))) : kLimit;
    }
    return c;
  }
  static int64_t key_of(const Eigen::Vector3i& c) {
    const auto part = [](int v) { return static_cast<int64_t>(v + (1 << (kBits - 1))); };
    return (part(c.x()) << (2 * kBits)) | (part(c.y()) << kBits) | part(c.z());
  }
  double side_;
  std::vector<size_t> order_;
  std::vector<int64_t> keys_, sorted_keys_;
};

// Colour compared by its chromaticity (r and g over r + g + b) and a little of its brightness:
// one object's faces differ in shading more than in hue (scene 1's box against the bench it
// stands on: RGB 0.982 / 0.476 from one click, chromaticity 0.992 / 0.955; 2026-12-03).
Eigen::Vector3f chromaticity(const Eigen::Vector3f& rgb, double brightness_weight) {
  const Eigen::Vector3f c = rgb.cwiseMax(0.f);
  const float sum = std::max(c.sum(), 0.05f);
  return {c.x() / sum, c.y() / sum, static_cast<float>(brightness_weight) * sum / 3};
}

// The typical distance between neighbouring points near `seed` (the median of each one's nearest
// neighbour's, for up to 256 of those within 32 `pixel`s of it; 0 when too few): how far apart a
// splat file's splats or a coarse reconstruction's points lie, whatever the clicked view's pixels.
double spacing_near(const std::vector<Eigen::Vector3d>& points, size_t seed, double pixel) {
  const double reach2 = (32 * pixel) * (32 * pixel);
  std::vector<size_t> near;
  for (size_t i = 0; i < points.size(); ++i)
    if ((points[i] - points[seed]).squaredNorm() <= reach2) near.push_back(i);
  if (near.size() < 8) return 0;
  const size_t step = std::max<size_t>(1, near.size() / 256);
  std::vector<double> nearest;
  for (size_t a = 0; a < near.size(); a += step) {
    double best = std::numeric_limits<double>::infinity();
    for (const size_t b : near)
      if (b != near[a]) best = std::min(best, (points[b] - points[near[a]]).squaredNorm());
    nearest.push_back(std::sqrt(best));
  }
  std::nth_element(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(nearest.size() / 2), nearest.end());
  return nearest[nearest.size() / 2];
}

// The points (`hue`: their chromaticity) connected to `seed` through neighbours within `link` of
// each other whose colours stay alike (SelectOptions' step and spread). `at_edge` is set when one
// of them lies farther than `edge` from the seed.
std::vector<uint8_t> grown_by_colour(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3f>& hue,
                                     size_t seed, double link, double edge, const SelectOptions& options,
                                     bool& at_edge) {
  const double link2 = link * link;
  const auto step = static_cast<float>(options.colour_step), spread = static_cast<float>(options.colour_spread);
  const PointGrid grid(points, link);
  // The colour around the click: its neighbours' mean (one point's colour is noisy).
  Eigen::Vector3f around = Eigen::Vector3f::Zero();
  int count = 0;
  grid.around(points[seed], [&](size_t j) {
    if ((points[j] - points[seed]).squaredNorm() <= link2) around += hue[j], ++count;
  });
  around /= static_cast<float>(std::max(1, count));

  std::vector<uint8_t> taken(points.size(), 0);
  std::deque<size_t> frontier = {seed};
  taken[seed] = 1;
  while (!frontier.empty()) {
    const size_t i = frontier.front();
    frontier.pop_front();
    at_edge |= (points[i] - points[seed]).norm() > edge;
    grid.around(points[i], [&](size_t j) {
      if (taken[j] || (points[j] - points[i]).squaredNorm() > link2) return;
      if ((hue[j] - hue[i]).norm() > step || (hue[j] - around).norm() > spread) return;
      taken[j] = 1;
      frontier.push_back(j);
    });
  }
  return taken;
}

double camera_depth(const Camera& camera, const Eigen::Vector3d& point) {
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  return (w2c.topLeftCorner<3, 3>() * point + w2c.topRightCorner<3, 1>()).z();
}

}  // namespace

void check_click_inside(const Camera& camera, const std::string& view, const Click& click) {
  const int W = camera.K.width, H = camera.K.height;
  if (!(click.x >= 0 && click.y >= 0 && click.x < W && click.y < H))
    fail("the click ({}, {}) is outside view {}'s image ({}x{})", click.x, click.y, view, W, H);
}

void check_clicks_inside(const Camera& camera, const std::string& view, const std::vector<Click>& clicks,
                         const std::vector<Click>& not_clicks) {
  for (const Click& click : clicks) check_click_inside(camera, view, click);
  for (const Click& click : not_clicks) check_click_inside(camera, view, click);
}

std::vector<size_t> clicked_points(const Camera& camera, const std::string& view,
                                   const std::vector<Eigen::Vector3d>& points, const Click& click,
                                   const SelectOptions& options, size_t* under_count) {
  check_click_inside(camera, view, click);
  const int W = camera.K.width, H = camera.K.height;
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  const double radius = std::max(2.0, options.pick_radius * std::max(W, H));
  std::vector<double> depths;
  std::vector<std::pair<double, size_t>> under;  // (depth, point) of those near the click
  for (size_t i = 0; i < points.size(); ++i) {
    const std::optional<PixelOfPoint> hit = pixel_of_point(camera.K, w2c, points[i]);
    if (!hit) continue;
    depths.push_back(hit->z);
    if (std::hypot(hit->x + 0.5 - click.x, hit->y + 0.5 - click.y) <= radius) under.emplace_back(hit->z, i);
  }
  if (under.empty())
    fail("nothing was reconstructed at the click ({}, {}) on view {}: click on an object", click.x, click.y, view);
  if (under_count) *under_count = under.size();
  // The surface the view sees there: near the front of the points under the click, not the very
  // nearest (a stray Gaussian floats in front of many surfaces).
  std::sort(under.begin(), under.end());
  auto at = [&](double q) { return under[static_cast<size_t>(q * static_cast<double>(under.size() - 1))]; };
  const double best_z = at(0.25).first;
  const auto k = static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(depths.size() - 1));
  std::nth_element(depths.begin(), depths.begin() + k, depths.end());
  const double far = std::max(depths[static_cast<size_t>(k)], options.scene_far.value_or(0.0));
  if (best_z > options.far_background * far)
    fail("the click ({}, {}) on view {} is on the sky or the far background ({:.3g} deep, the view's far depth "
         "{:.3g}): click on an object",
         click.x, click.y, view, best_z, far);
  // That point first, then points across the depths under the click: when strays lie at the
  // front quarter, the middle is the surface.
  std::vector<size_t> out;
  for (const double q : {0.25, 0.5, 0.35, 0.15, 0.45, 0.6, 0.05, 0.75}) {
    const size_t i = at(q).second;
    if (std::find(out.begin(), out.end(), i) == out.end()) out.push_back(i);
  }
  return out;
}

size_t clicked_point(const Camera& camera, const std::string& view, const std::vector<Eigen::Vector3d>& points,
                     const Click& click, const SelectOptions& options) {
  return clicked_points(camera, view, points, click, options, nullptr).front();
}

std::vector<uint8_t> grow_selection(const std::vector<Eigen::Vector3d>& points,
                                    const std::vector<Eigen::Vector3f>& colours, size_t seed, const Camera& camera,
                                    const SelectOptions& options) {
  if (colours.size() != points.size()) fail("select: {} points but {} colours", points.size(), colours.size());
  if (seed >= points.size()) fail("select: the seed {} is not one of the {} points", seed, points.size());
  const double z = camera_depth(camera, points[seed]);
  if (!(z > 0)) fail("select: the clicked point is behind the camera");
  const double pixel = z / camera.K.fx;  // a pixel of the clicked view at the clicked depth
  const double link = std::max(options.link_pixels * pixel, options.link_spacing * spacing_near(points, seed, pixel));

  // Grown among the points within `reach` of the seed; again within a farther reach when the
  // selection comes within a link of its edge (a path could leave and come back). An object is
  // small beside a scene of a million splats: its neighbourhood's grid is sorted, not the scene's.
  for (double reach = 32 * link;; reach *= 4) {
    std::vector<size_t> near;
    for (size_t i = 0; i < points.size(); ++i)
      if ((points[i] - points[seed]).squaredNorm() <= reach * reach) near.push_back(i);
    std::vector<Eigen::Vector3d> local(near.size());
    std::vector<Eigen::Vector3f> hue(near.size());
    size_t local_seed = 0;
    for (size_t k = 0; k < near.size(); ++k) {
      local[k] = points[near[k]];
      hue[k] = chromaticity(colours[near[k]], options.brightness_weight);
      if (near[k] == seed) local_seed = k;
    }
    bool at_edge = false;
    const std::vector<uint8_t> taken = grown_by_colour(local, hue, local_seed, link, reach - link, options, at_edge);
    if (at_edge && near.size() < points.size()) continue;
    std::vector<uint8_t> selected(points.size(), 0);
    for (size_t k = 0; k < near.size(); ++k) selected[near[k]] = taken[k];
    return selected;
  }
}

std::vector<uint8_t> select_object(const Camera& camera, const std::string& view,
                                   const std::vector<Eigen::Vector3d>& points,
                                   const std::vector<Eigen::Vector3f>& colours, const Click& click,
                                   const SelectOptions& options) {
  // The clicked point grown; when it joins too few (a stray point at an edge, of its own colour),
  // the next points under the click on the same surface, until one reaches options.min_points.
  size_t under = 0;
  const std::vector<size_t> seeds = clicked_points(camera, view, points, click, options, &under);
  // An object holds at least half of the points under the click (they cover its pick disc).
  const size_t enough = std::max(options.min_points, under / 2);
  std::vector<uint8_t> selected;
  size_t most = 0;
  for (size_t t = 0; t < std::min<size_t>(seeds.size(), options.seed_tries); ++t) {
    std::vector<uint8_t> grown = grow_selection(points, colours, seeds[t], camera, options);
    const auto n = static_cast<size_t>(std::count(grown.begin(), grown.end(), uint8_t{1}));
    if (t == 0 || n > most) selected = std::move(grown), most = n;
    if (most >= enough) break;
  }
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  size_t seen = 0, taken = 0;
  for (size_t i = 0; i < points.size(); ++i)
    if (pixel_of_point(camera.K, w2c, points[i])) ++seen, taken += selected[i];
  const double share = static_cast<double>(taken) / static_cast<double>(std::max<size_t>(1, seen));
  if (share > options.max_share)
    fail("the click ({}, {}) on view {} selects {:.0f} % of what the view sees (the ground, a wall or the sky?): "
         "click on an object",
         click.x, click.y, view, 100 * share);
  return selected;
}

std::vector<uint8_t> select_objects(const Camera& camera, const std::string& view,
                                    const std::vector<Eigen::Vector3d>& points,
                                    const std::vector<Eigen::Vector3f>& colours, const std::vector<Click>& clicks,
                                    const SelectOptions& options) {
  std::vector<uint8_t> selected(points.size(), 0);
  for (const Click& click : clicks) {
    const std::vector<uint8_t> one = select_object(camera, view, points, colours, click, options);
    for (size_t i = 0; i < selected.size(); ++i) selected[i] |= one[i];
  }
  return selected;
}

Image selection_mask(const Camera& camera, const std::vector<Eigen::Vector3d>& points,
                     const std::vector<uint8_t>& selected, int radius, int dilation) {
  cv::Mat canvas(camera.K.height, camera.K.width, CV_8UC1, cv::Scalar(0));
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  for (size_t i = 0; i < points.size(); ++i) {
    if (!selected[i]) continue;
    if (const std::optional<PixelOfPoint> hit = pixel_of_point(camera.K, w2c, points[i]))
      cv::circle(canvas, cv::Point(hit->x, hit->y), std::max(0, radius), cv::Scalar(1), cv::FILLED);
  }
  return finish_mask(canvas, dilation);
}

std::vector<CarvedMask> selection_masks(const std::vector<Camera>& cameras, const PhotoSource& photo,
                                        const std::vector<Eigen::Vector3d>& points,
                                        const std::vector<uint8_t>& selected, const SelectOptions& options,
                                        const CarveOptions& carving) {
  std::vector<Image> masks(cameras.size());
  parallel_dynamic(static_cast<int64_t>(cameras.size()), thread_plan().cores, [&](int64_t i) {
    const Camera& camera = cameras[static_cast<size_t>(i)];
    const int side = std::max(camera.K.width, camera.K.height);
    masks[static_cast<size_t>(i)] =
        selection_mask(camera, points, selected, std::max(1, static_cast<int>(0.003 * side)),
                       std::max(2, static_cast<int>(std::lround(options.mask_margin * side))));
  });
  std::vector<PointRole> roles(selected.size());
  for (size_t i = 0; i < selected.size(); ++i) roles[i] = selected[i] ? PointRole::object : PointRole::other;
  return carve_masks(masks, photo, cameras, points, roles, carving);
}

}  // namespace ii
