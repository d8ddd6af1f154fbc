#include "fill/region.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "common/error.h"
#include "common/torch.h"
#include "data/image_ops.h"
#include "data/masks.h"
#include "data/scene.h"
#include "edit/box_select.h"
#include "fill/cameras.h"
#include "fill/whole_object.h"
#include "eval/metrics.h"
#include "gaussians/gaussians.h"
#include "render/projection.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace ii {

namespace {

Eigen::Vector3d position(const SplatCloud& cloud, size_t i) {
  return {cloud.means[3 * i], cloud.means[3 * i + 1], cloud.means[3 * i + 2]};
}

// A splat's colour (RGB in [0, 1]) by its first spherical-harmonics coefficients.
Eigen::Vector3f colour_of(const SplatCloud& cloud, size_t i) {
  return {static_cast<float>(colour_of_dc(cloud.sh_dc[3 * i])), static_cast<float>(colour_of_dc(cloud.sh_dc[3 * i + 1])),
          static_cast<float>(colour_of_dc(cloud.sh_dc[3 * i + 2]))};
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * static_cast<double>(values.size() - 1)));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

// The positions' exact bits, for matching splats between two files of one scene.
struct PositionKey {
  uint32_t x, y, z;
  bool operator==(const PositionKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct PositionHash {
  size_t operator()(const PositionKey& k) const {
    return (static_cast<size_t>(k.x) * 73856093u) ^ (static_cast<size_t>(k.y) * 19349663u) ^
           (static_cast<size_t>(k.z) * 83492791u);
  }
};
PositionKey key_of(const SplatCloud& cloud, size_t i) {
  PositionKey k;
  std::memcpy(&k.x, &cloud.means[3 * i], 4);
  std::memcpy(&k.y, &cloud.means[3 * i + 1], 4);
  std::memcpy(&k.z, &cloud.means[3 * i + 2], 4);
  return k;
}

// Matches by the nearest kept position within `tolerance` (a grid of that cell size).
RegionMask missing_within(const SplatCloud& cloud, const SplatCloud& kept, double tolerance) {
  auto cell = [&](const Eigen::Vector3d& p) {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / tolerance)), static_cast<int>(std::floor(p.y() / tolerance)),
                           static_cast<int>(std::floor(p.z() / tolerance)));
  };
  auto cell_key = [](const Eigen::Vector3i& c) {
    return (static_cast<int64_t>(c.x()) * 73856093) ^ (static_cast<int64_t>(c.y()) * 19349663) ^
           (static_cast<int64_t>(c.z()) * 83492791);
  };
  std::unordered_map<int64_t, std::vector<uint32_t>> grid;
  for (size_t i = 0; i < kept.size(); ++i) grid[cell_key(cell(position(kept, i)))].push_back(static_cast<uint32_t>(i));
  RegionMask region(cloud.size(), true);
  for (size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = position(cloud, i);
    const Eigen::Vector3i c = cell(p);
    for (int dx = -1; dx <= 1 && region[i]; ++dx)
      for (int dy = -1; dy <= 1 && region[i]; ++dy)
        for (int dz = -1; dz <= 1 && region[i]; ++dz) {
          const auto found = grid.find(cell_key(c + Eigen::Vector3i(dx, dy, dz)));
          if (found == grid.end()) continue;
          for (uint32_t j : found->second)
            if ((position(kept, j) - p).norm() <= tolerance) {
              region[i] = false;
              break;
            }
        }
  }
  return region;
}

// What `camera` sees of the splats within a box of its picture: depth and opacity, row-major over the
// box. Only the box is drawn, with the splats that reach into it: drawing the whole view of a million
// splats took most of a page's click (docs/benchmarks.md, "Selecting the object"; CHANGELOG.md,
// 2026-12-03).
struct SurfaceInBox {
  int x0 = 0, y0 = 0, width = 0, height = 0;
  std::vector<float> depth, alpha;
};
SurfaceInBox surface_in_box(const SplatCloud& cloud, const Camera& camera, const std::optional<PixelBox>& box) {
  SurfaceInBox out;
  if (!box || box->empty()) return out;
  out.x0 = box->x0, out.y0 = box->y0, out.width = box->width(), out.height = box->height();
  const Camera part = camera.cropped(out.x0, out.y0, out.width, out.height);
  torch::NoGradGuard no_grad;
  const GaussianSet splats = gaussians_from_splats(cloud, 0);
  const PixelWindow whole{0, 0, static_cast<double>(out.width), static_cast<double>(out.height)};
  const RenderOutput seen = render(select_rows(splats, reaching_window(splats, part, whole)), {part});
  const torch::Tensor depth = seen.depth.squeeze(2).reshape({-1}).contiguous();
  const torch::Tensor alpha = seen.alpha.squeeze(2).reshape({-1}).contiguous();
  out.depth.assign(depth.data_ptr<float>(), depth.data_ptr<float>() + depth.numel());
  out.alpha.assign(alpha.data_ptr<float>(), alpha.data_ptr<float>() + alpha.numel());
  return out;
}

}  // namespace

RegionMask region_in_box(const SplatCloud& cloud, const OrientedBox& box) {
  RegionMask region(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) region[i] = box.contains(position(cloud, i));
  return region;
}

RegionMask region_missing_from(const SplatCloud& cloud, const SplatCloud& kept, const std::string& kept_name) {
  std::unordered_set<PositionKey, PositionHash> kept_keys;
  kept_keys.reserve(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) kept_keys.insert(key_of(kept, i));
  RegionMask region(cloud.size());
  size_t matched = 0;
  for (size_t i = 0; i < cloud.size(); ++i) {
    region[i] = kept_keys.count(key_of(cloud, i)) == 0;
    matched += region[i] ? 0 : 1;
  }
  if (matched * 2 < kept.size()) {  // re-quantised positions: the nearest within a tolerance
    const auto [lo, hi] = splat_bounds(cloud);
    region = missing_within(cloud, kept, std::max(1e-9, 1e-3 * (hi - lo).norm()));
    matched = cloud.size() - static_cast<size_t>(region_count(region));
  }
  if (kept.size() > cloud.size() || static_cast<double>(matched) < 0.9 * static_cast<double>(kept.size()))
    fail("--selection {}: {} of its {} splats are not in the scene: it is not this scene with some splats deleted",
         kept_name, kept.size() - std::min(kept.size(), matched), kept.size());
  return region;
}

RegionMask region_under_stroke(const SplatCloud& cloud, const Camera& camera, const Image& stroke_in) {
  const int W = camera.K.width, H = camera.K.height;
  if (!mask_near_size(stroke_in, W, H))
    fail("--mask: {}x{} pixels, but the view's camera is {}x{}", stroke_in.width, stroke_in.height, W, H);
  if (stroke_in.width != W || stroke_in.height != H)
    spdlog::warn("--mask: {}x{} pixels, the view's camera {}x{}: resized nearest-neighbour", stroke_in.width,
                 stroke_in.height, W, H);
  // A stroke drawn over an object leaves its rim out: grown by about 1 % of the view.
  const int grow = std::max(1, std::min(W, H) / 100);
  const Image drawn = resize_nearest(stroke_in, W, H);
  const Image stroke = dilate_mask(drawn, 1, 2 * grow + 1);
  const SurfaceInBox seen = surface_in_box(cloud, camera, mask_bounding_box(drawn));
  // The marked surface: its camera depths and, for its width, its points in the camera's frame.
  std::vector<double> depths, xs, ys;
  for (int y = seen.y0; y < seen.y0 + seen.height; ++y)
    for (int x = seen.x0; x < seen.x0 + seen.width; ++x) {
      const size_t i = static_cast<size_t>(y - seen.y0) * seen.width + (x - seen.x0);
      if (drawn.at(y, x) <= 0.5f || seen.alpha[i] < 0.5f) continue;
      const double d = seen.depth[i];
      depths.push_back(d);
      xs.push_back((x + 0.5 - camera.K.cx) / camera.K.fx * d);
      ys.push_back((y + 0.5 - camera.K.cy) / camera.K.fy * d);
    }
  if (depths.empty()) fail("--mask: the stroke covers no surface of the scene in this view (nothing is drawn there)");
  const double width = std::max({percentile(xs, 0.98) - percentile(xs, 0.02), percentile(ys, 0.98) - percentile(ys, 0.02),
                                 1e-6});
  const double margin = 0.1 * width, near = percentile(depths, 0.02) - margin, far = percentile(depths, 0.98) + width;
  // The splats whose centres fall in the stroke, from the nearest of the marked surface (a pixel's
  // depth is an average over the splats it draws: the front ones lie nearer) to as far behind it
  // as it is wide.
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  RegionMask region(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    const std::optional<PixelOfPoint> hit = pixel_of_point(camera.K, w2c, position(cloud, i));
    region[i] = hit && stroke.at(hit->y, hit->x) > 0.5f && hit->z >= near && hit->z <= far;
  }
  return region;
}

namespace {

// What `camera` sees of the splats at about the page's working size (256 rows), as a photo and its
// per-pixel reconstruction: one point per pixel the splats cover (alpha >= 0.5) at the render's
// depth, in the render's colour, as the network gives a photo one Gaussian per pixel.
struct RenderedView {
  Camera camera;  // the picture's
  Image picture;
  GaussianSet gaussians;         // the splats drawn
  torch::Tensor depth, covered;  // (H, W) on the CPU: the render's depth, where it covers
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3f> colours;
};

RenderedView rendered_view(const SplatCloud& cloud, const Camera& camera) {
  torch::NoGradGuard no_grad;
  constexpr int kRows = 256;
  RenderedView r;
  const double scale = std::min(1.0, double(kRows) / camera.K.height);
  r.camera = camera.resized(std::max(1, static_cast<int>(std::lround(camera.K.width * scale))),
                            std::max(1, static_cast<int>(std::lround(camera.K.height * scale))));
  r.gaussians = gaussians_from_splats(cloud, 0);
  const RenderOutput out = render(r.gaussians, {r.camera});
  r.picture = image_from_hwc(out.rgb.clamp(0, 1).to(torch::kCPU, torch::kFloat32));
  const torch::Tensor covered = (out.alpha.squeeze(2) >= 0.5).logical_and(out.depth.squeeze(2) > 0).to(torch::kCPU);
  r.depth = out.depth.squeeze(2).to(torch::kCPU, torch::kFloat32).contiguous();
  r.covered = covered;
  const torch::Tensor pixels = covered.nonzero();
  const torch::Tensor v = pixels.select(1, 0).to(torch::kFloat64), u = pixels.select(1, 1).to(torch::kFloat64);
  const torch::Tensor z = out.depth.squeeze(2).to(torch::kCPU, torch::kFloat64).index({covered});
  const torch::Tensor xyz = unproject(r.camera, v, u, z).contiguous();
  const torch::Tensor rgb = out.rgb.to(torch::kCPU, torch::kFloat32).index({covered}).contiguous();
  const double* p = xyz.data_ptr<double>();
  const float* c = rgb.data_ptr<float>();
  for (int64_t i = 0; i < xyz.size(0); ++i) {
    r.points.emplace_back(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    r.colours.emplace_back(c[3 * i], c[3 * i + 1], c[3 * i + 2]);
  }
  return r;
}

// Each click's splat grown over its neighbours alike in colour, among the opaque splats;
// `outline_share` receives the share of the view its outline covers.
RegionMask region_grown_over_splats(const SplatCloud& cloud, const Camera& camera, const std::string& view,
                                    const std::vector<Click>& clicks, const SelectOptions& options,
                                    double& outline_share) {
  // Grown over the opaque splats: faint ones float around every object and bridge it to the rest.
  // Opaque: above 0.5, or in the most opaque quarter where fewer are (a refined or another tool's
  // file can be mostly translucent: scene 1 refined for 3 minutes, 2 % above 0.5, median 0.02).
  std::vector<float> logits(cloud.opacity_logit.begin(), cloud.opacity_logit.end());
  const auto upper = static_cast<std::ptrdiff_t>(0.75 * static_cast<double>(logits.size() - 1));
  std::nth_element(logits.begin(), logits.begin() + upper, logits.end());
  const float threshold = logits.empty() ? 0.f : std::min(0.f, logits[static_cast<size_t>(upper)]);
  std::vector<size_t> opaque;
  for (size_t i = 0; i < cloud.size(); ++i)
    if (cloud.opacity_logit[i] > threshold || (threshold < 0.f && cloud.opacity_logit[i] == threshold)) opaque.push_back(i);
  std::vector<Eigen::Vector3d> points(opaque.size());
  std::vector<Eigen::Vector3f> colours(opaque.size());
  for (size_t k = 0; k < opaque.size(); ++k) {
    const size_t i = opaque[k];
    points[k] = position(cloud, i);
    colours[k] = colour_of(cloud, i);
  }
  const std::vector<uint8_t> selected = select_objects(camera, view, points, colours, clicks, options);
  // The selection's outline in the view taken as a stroke: with it go the splats it misses
  // (faint ones, another shade of the object, its hidden back), as a stroke over it would take.
  const int side = std::max(camera.K.width, camera.K.height);
  const Image outline = selection_mask(camera, points, selected, std::max(1, side / 300), 0);
  outline_share = std::count_if(outline.pixels.begin(), outline.pixels.end(), [](float v) { return v > 0.5f; }) /
                  std::max(1.0, double(outline.pixels.size()));
  RegionMask region = region_under_stroke(cloud, camera, outline);
  for (size_t k = 0; k < opaque.size(); ++k) region[opaque[k]] = region[opaque[k]] || selected[k];
  return region;
}

}  // namespace

// A selection's outline smaller than this share of the view is a speck, not an object.
constexpr double kSpeck = 0.005;

// A splat drawn at a pixel lies this far behind the render's (expected) depth there at most: a
// trained file's surfaces are several splats deep (the ring rooms: 10 % behind on average).
constexpr double kOnTheSurface = 1.15;

// Where `part` shows in `seen`: it draws at least half a pixel there, not behind what the render shows.
torch::Tensor part_pixels(const RenderedView& seen, const RegionMask& part) {
  torch::NoGradGuard no_grad;
  const RenderOutput drawn = render(select_rows(seen.gaussians, region_flags(part, torch::kCPU)), {seen.camera});
  const torch::Tensor depth = drawn.depth.squeeze(2).to(torch::kCPU, torch::kFloat32);
  return (drawn.alpha.squeeze(2).to(torch::kCPU) >= 0.5)
      .logical_and(depth <= seen.depth * static_cast<float>(kOnTheSurface))
      .logical_and(seen.covered);
}

// The scene's up: the axis guess_up finds, turned the way the camera's own up points when the
// photo was taken upright (fewer splats above the object than below, guess_up's sign, is not
// always so: a room's far walls).
Eigen::Vector3d scene_up(const SplatCloud& cloud, const Camera& camera, const RegionMask& part) {
  Eigen::Vector3d up = guess_up(cloud, part);
  if (camera.c2w.block<3, 1>(0, 1).dot(up) < -0.5) up = -up;
  return up;
}

// `part`, selected by `outline` in `seen`, with the rest of the object it belongs to
// (fill/whole_object.h), lifted as a stroke; `part` alone when no object is found.
RegionMask with_the_whole_object(const SplatCloud& cloud, const RenderedView& seen, const Image& outline,
                                 const RegionMask& part) {
  // The part's pixels: where its splats draw, or its outline where they are too few to draw (a
  // click on a patterned body grows over a speck).
  const torch::Tensor outlined = image_to_tensor(outline)[0][0].gt(0.5f);
  const std::optional<ObjectAboveSupport> object = object_above_support(
      seen.camera, seen.picture, seen.depth, seen.covered, part_pixels(seen, part).logical_or(outlined),
      scene_up(cloud, seen.camera, part));
  if (!object) return part;
  // The stroke reaches as far behind the object as it is wide (the table top behind it): what lies
  // on or under the surface the object stands on is left out, unless the object's pixels show it
  // (its thin foot, a disc on the table) or it lies under the object, and so is what lies out of
  // the object's reach.
  RegionMask region = region_under_stroke(cloud, seen.camera, object->mask);
  const Eigen::Matrix4d w2c = seen.camera.w2c_opencv();
  const float* drawn_depth = seen.depth.data_ptr<float>();
  const int w = seen.camera.K.width;
  for (size_t i = 0; i < region.size(); ++i) {
    if (part[i] || !region[i]) {
      region[i] = part[i];
      continue;
    }
    const Eigen::Vector3d p = position(cloud, i);
    const std::optional<PixelOfPoint> hit = pixel_of_point(seen.camera.K, w2c, p);
    if (!hit || !object->within_reach(p, hit->z)) {
      region[i] = false;
    } else if (p.dot(object->up) <= object->above) {
      region[i] = (object->under(p) && object->coloured_like_it(colour_of(cloud, i))) ||
                  (object->mask.at(hit->y, hit->x) > 0.5f && hit->z <= kOnTheSurface * drawn_depth[hit->y * w + hit->x]);
    }
  }
  return region;
}

RegionMask region_from_clicks(const SplatCloud& cloud, const Camera& camera, const std::string& view,
                              const std::vector<Click>& clicks, const SelectOptions& options) {
  // Grown over the splats first. On a trained file (3DGS, reconstruct: translucent splats unlike in
  // colour) that stops at once, a speck: then selected in the render as a photo is. On the statue
  // reconstructed, 8 clicks: recall 0.021 over the splats, 0.913 / precision 0.848 in the render; on
  // the network's statue the render gave 0.981 / 0.548 against 0.979 / 0.746 over the splats
  // (2026-12-07, docs/editing.md).
  check_clicks_inside(camera, view, clicks, {});
  std::optional<RegionMask> grown;
  try {
    double outline_share = 0;
    grown = region_grown_over_splats(cloud, camera, view, clicks, options, outline_share);
    if (outline_share < kSpeck) grown.reset();
  } catch (const Error&) {
    // No opaque splat at the click (a translucent file): the render may still show the object there.
  }
  // Opaque splats grown: their part as it is (the render the whole object needs cost the network's
  // statue 0.4 s of 1.5 s a click, and changed none of its clicks).
  if (grown) return *grown;
  const RenderedView seen = rendered_view(cloud, camera);
  const double sx = double(seen.camera.K.width) / camera.K.width, sy = double(seen.camera.K.height) / camera.K.height;
  std::vector<Click> scaled;
  for (const Click& c : clicks) scaled.push_back({c.x * sx, c.y * sy});
  const std::vector<uint8_t> selected =
      select_objects(seen.camera, view, seen.points, seen.colours, scaled, options);
  const Image outline =
      selection_masks({seen.camera}, [&](size_t) { return seen.picture; }, seen.points, selected, options)[0].mask;
  return with_the_whole_object(cloud, seen, outline, region_under_stroke(cloud, seen.camera, outline));
}

Image splats_seen(const SplatCloud& cloud, const Camera& camera) {
  torch::NoGradGuard no_grad;
  return image_from_hwc(render(gaussians_from_splats(cloud, 0), {camera}).rgb);
}

RegionMask region_from_segmented_clicks(const SplatCloud& cloud, const Camera& camera, const std::string& view,
                                        const std::vector<Click>& clicks, const std::vector<Click>& not_clicks,
                                        const Segmenter& segmenter, ClickedMask* clicked) {
  check_clicks_inside(camera, view, clicks, not_clicks);
  ClickedMask mask;
  try {
    mask = mask_from_clicks(segmenter, splats_seen(cloud, camera), clicks, not_clicks);
  } catch (const Error& e) {
    fail("view {}: {}", view, e.what());
  }
  RegionMask region = region_under_stroke(cloud, camera, mask.mask);
  if (clicked) *clicked = std::move(mask);
  return region;
}

RegionMask region_from_view_box(const SplatCloud& cloud, const Camera& camera, const std::string& view,
                                const ViewBox& box, const std::vector<Click>& clicks,
                                const std::vector<Click>& not_clicks, const Segmenter* segmenter,
                                ClickedMask* clicked) {
  check_clicks_inside(camera, view, clicks, not_clicks);
  check_box(view, camera.K.width, camera.K.height, box, clicks, segmenter != nullptr);
  const Image seen = splats_seen(cloud, camera);
  if (!segmenter) {
    // GrabCut's edge pixels mix the object with what lies behind it, and a stroke pixel on the wall
    // behind selects the wall's splats there: the stroke one pixel in from GrabCut's edge (the
    // region grows through the object's depth anyway).
    Image outside = object_in_box(seen, view, box, clicks, not_clicks);
    for (float& v : outside.pixels) v = 1.f - v;
    Image inside = dilate_mask(outside, 1, 3);
    for (float& v : inside.pixels) v = 1.f - v;
    return region_under_stroke(cloud, camera, inside);
  }
  ClickedMask mask;
  try {
    mask = mask_from_prompt(*segmenter, seen, clicks, not_clicks, box);
  } catch (const Error& e) {
    fail("view {}: {}", view, e.what());
  }
  RegionMask region = region_under_stroke(cloud, camera, mask.mask);
  if (clicked) *clicked = std::move(mask);
  return region;
}

int64_t region_count(const RegionMask& region) {
  return static_cast<int64_t>(std::count(region.begin(), region.end(), true));
}

std::pair<Eigen::Vector3d, Eigen::Vector3d> splat_bounds(const SplatCloud& cloud, const RegionMask* only) {
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> v;
    for (size_t i = 0; i < cloud.size(); ++i)
      if (!only || (*only)[i]) v.push_back(cloud.means[3 * i + static_cast<size_t>(axis)]);
    lo[axis] = percentile(v, 0.01);
    hi[axis] = percentile(v, 0.99);
  }
  return {lo, hi};
}

void check_splats_finite(const SplatCloud& cloud, const std::string& name) {
  auto check = [&](const std::vector<float>& values, size_t per_splat, const char* what) {
    for (size_t j = 0; j < values.size(); ++j)
      if (!std::isfinite(values[j]))
        fail("{}: splat {} has a non-finite {} ({}): the file is damaged", name, j / per_splat, what, values[j]);
  };
  check(cloud.means, 3, "position");
  check(cloud.log_scales, 3, "scale");
  check(cloud.rotations, 4, "rotation");
  check(cloud.opacity_logit, 1, "opacity");
  check(cloud.sh_dc, 3, "colour");
}

}  // namespace ii
