#include "data/masks.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <memory>
#include <mutex>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "common/error.h"
#include "data/photo_points.h"
#include "io/npy.h"

namespace ii {

namespace fs = std::filesystem;

int random_int(MaskRng& rng, int lo, int hi_inclusive) {
  if (hi_inclusive < lo) fail("random_int: empty range [{}, {}]", lo, hi_inclusive);
  // Lemire's multiply-and-reject: unbiased, one 64-bit draw almost always.
  const uint64_t range = static_cast<uint64_t>(static_cast<int64_t>(hi_inclusive) - lo) + 1;
  unsigned __int128 product = static_cast<unsigned __int128>(rng()) * range;
  if (static_cast<uint64_t>(product) < range) {
    const uint64_t threshold = (0 - range) % range;
    while (static_cast<uint64_t>(product) < threshold) product = static_cast<unsigned __int128>(rng()) * range;
  }
  return static_cast<int>(lo + static_cast<int64_t>(product >> 64));
}

double random_unit(MaskRng& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

namespace {

void check_mask_size(int width, int height, const char* what) {
  if (width <= 0 || height <= 0) fail("{}: mask size {}x{} must be positive", what, width, height);
}

}  // namespace

std::string mask_mode_name(MaskMode mode) {
  switch (mode) {
    case MaskMode::Instance: return "instance";
    case MaskMode::Random: return "random";
    case MaskMode::Consistent3D: return "3dconsistent";
  }
  return "unknown";
}

MaskMode draw_mask_mode(const std::array<double, 3>& weights, MaskRng& rng) {
  double total = 0;
  for (double w : weights) {
    if (!std::isfinite(w) || w < 0)
      fail("mask mix weights must be finite and non-negative, got ({}, {}, {})", weights[0], weights[1],
           weights[2]);
    total += w;
  }
  if (total <= 0) fail("mask mix weights ({}, {}, {}) sum to zero", weights[0], weights[1], weights[2]);
  const double draw = random_unit(rng) * total;
  if (draw < weights[0]) return MaskMode::Instance;
  if (draw < weights[0] + weights[1] || weights[2] == 0) return MaskMode::Random;
  return MaskMode::Consistent3D;
}

Image dilate_mask(const Image& mask, int iterations, int kernel_size) {
  if (mask.channels != 1) fail("dilate_mask: expected a 1-channel mask, got {} channels", mask.channels);
  if (iterations <= 0 || mask.empty()) return mask;
  Image out = mask;
  cv::Mat m(out.height, out.width, CV_32FC1, out.pixels.data());
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(kernel_size, kernel_size));
  cv::dilate(m, m, kernel, cv::Point(-1, -1), iterations, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

Image mask_union(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels != b.channels)
    fail("mask_union: masks of different sizes ({}x{}x{} and {}x{}x{})", a.width, a.height, a.channels,
         b.width, b.height, b.channels);
  Image out = a;
  for (size_t i = 0; i < out.pixels.size(); ++i) out.pixels[i] = std::max(a.pixels[i], b.pixels[i]);
  return out;
}

std::vector<Rectangle> random_rectangles(int width, int height, int count, MaskRng& rng) {
  check_mask_size(width, height, "random_rectangles");
  std::vector<Rectangle> out;
  // Sizes in [S/6, S/4) as in the official code; tiny images still get one-pixel rectangles.
  const int w_lo = std::max(1, width / 6), w_hi = std::max(w_lo, width / 4 - 1);
  const int h_lo = std::max(1, height / 6), h_hi = std::max(h_lo, height / 4 - 1);
  for (int k = 0; k < count; ++k) {
    Rectangle r;
    r.width = std::min(width, random_int(rng, w_lo, w_hi));
    r.height = std::min(height, random_int(rng, h_lo, h_hi));
    r.x = random_int(rng, 0, std::max(0, width - r.width - 1));
    r.y = random_int(rng, 0, std::max(0, height - r.height - 1));
    out.push_back(r);
  }
  return out;
}

Image rectangles_mask(int width, int height, const std::vector<Rectangle>& rectangles) {
  check_mask_size(width, height, "rectangles_mask");
  Image mask(width, height, 1);
  for (const Rectangle& r : rectangles)
    for (int y = std::max(0, r.y); y < std::min(height, r.y + r.height); ++y)
      for (int x = std::max(0, r.x); x < std::min(width, r.x + r.width); ++x) mask.at(y, x) = 1.f;
  return mask;
}

std::vector<Ellipse> random_ellipses(int width, int height, int count, MaskRng& rng) {
  check_mask_size(width, height, "random_ellipses");
  const int a0 = std::max(1, count <= 2 ? height / 8 : height / 12);
  const int a1 = std::max(a0 + 2, count <= 2 ? width / 6 : width / 8);
  std::vector<Ellipse> out;
  for (int k = 0; k < count; ++k) {
    Ellipse e;
    e.center_y = random_int(rng, 0, height - 1);
    e.center_x = random_int(rng, 0, width - 1);
    const int major = random_int(rng, a0 + 1, a1 - 1);
    e.major = major;
    e.minor = random_int(rng, a0, major - 1);
    e.angle = random_unit(rng) * M_PI;
    out.push_back(e);
  }
  return out;
}

Image ellipses_mask(int width, int height, const std::vector<Ellipse>& ellipses) {
  check_mask_size(width, height, "ellipses_mask");
  Image mask(width, height, 1);
  for (const Ellipse& e : ellipses) {
    const double c = std::cos(e.angle), s = std::sin(e.angle);
    // Only the bounding square of the major axis can hold inside pixels.
    const int r = static_cast<int>(std::ceil(e.major)) + 1;
    for (int y = std::max(0, static_cast<int>(e.center_y) - r);
         y <= std::min(height - 1, static_cast<int>(e.center_y) + r); ++y)
      for (int x = std::max(0, static_cast<int>(e.center_x) - r);
           x <= std::min(width - 1, static_cast<int>(e.center_x) + r); ++x) {
        const double dx = x - e.center_x, dy = y - e.center_y;
        const double xr = dx * c - dy * s, yr = dx * s + dy * c;
        if ((xr / e.major) * (xr / e.major) + (yr / e.minor) * (yr / e.minor) <= 1.0) mask.at(y, x) = 1.f;
      }
  }
  return mask;
}

std::vector<Image> carry_mask_through_depth(const Image& reference_mask, const Image& reference_depth,
                                            const Camera& reference_camera,
                                            const std::vector<Camera>& cameras, int dilations) {
  const Intrinsics& K = reference_camera.K;
  if (reference_mask.width != K.width || reference_mask.height != K.height || reference_mask.channels != 1)
    fail("carry_mask_through_depth: reference mask is {}x{}x{}, its camera is {}x{}", reference_mask.width,
         reference_mask.height, reference_mask.channels, K.width, K.height);
  if (reference_depth.width != K.width || reference_depth.height != K.height || reference_depth.channels != 1)
    fail("carry_mask_through_depth: reference depth is {}x{}x{}, its camera is {}x{}", reference_depth.width,
         reference_depth.height, reference_depth.channels, K.width, K.height);

  // World points of the masked reference pixels, through pixel centres (OpenGL camera axes).
  std::vector<Eigen::Vector3d> points;
  const Eigen::Matrix3d R = reference_camera.rotation();
  const Eigen::Vector3d origin = reference_camera.center();
  for (int i = 0; i < K.height; ++i)
    for (int j = 0; j < K.width; ++j) {
      if (reference_mask.at(i, j) < 0.5f) continue;
      const double depth = reference_depth.at(i, j);
      if (!std::isfinite(depth) || depth <= 0) continue;
      const Eigen::Vector3d d_cam(((j + 0.5) - K.cx) / K.fx, -((i + 0.5) - K.cy) / K.fy, -1.0);
      points.push_back(origin + depth * (R * d_cam));
    }

  std::vector<Image> out;
  for (const Camera& cam : cameras) {
    Image splat(cam.K.width, cam.K.height, 1);
    const Eigen::Matrix4d w2c = cam.w2c_opencv();
    for (const Eigen::Vector3d& X : points) {
      const Eigen::Vector3d Y = w2c.block<3, 3>(0, 0) * X + w2c.block<3, 1>(0, 3);
      if (Y.z() <= 1e-9) continue;  // behind the camera: not visible there
      const double u = cam.K.fx * Y.x() / Y.z() + cam.K.cx;
      const double v = cam.K.fy * Y.y() / Y.z() + cam.K.cy;
      if (!(u >= 0 && v >= 0 && u < cam.K.width && v < cam.K.height)) continue;
      splat.at(static_cast<int>(v), static_cast<int>(u)) = 1.f;
    }
    out.push_back(dilate_mask(splat, dilations, 5));
  }
  return out;
}

Image read_depth_map(const fs::path& file, int width, int height, double png_scale) {
  Image depth;
  if (file.extension() == ".npy") {
    const NpyArray array = read_npy(file);
    const bool shape_ok = (array.shape.size() == 2 || (array.shape.size() == 3 && array.shape[2] == 1));
    if (!shape_ok) fail_file(file, "depth must be an (H, W) or (H, W, 1) array");
    depth = Image(static_cast<int>(array.shape[1]), static_cast<int>(array.shape[0]), 1);
    depth.pixels = array.as_float();
  } else {
    const DecodedImage decoded = decode_image(file);
    if (decoded.bit_depth != 16) fail_file(file, "a depth image must be a 16-bit PNG (or a .npy array)");
    depth = Image(decoded.color.width, decoded.color.height, 1);
    // 16-bit levels times the scale; level 0 = unknown (stays 0).
    for (int y = 0; y < depth.height; ++y)
      for (int x = 0; x < depth.width; ++x)
        depth.at(y, x) = static_cast<float>(std::round(decoded.color.at(y, x) * 65535.0) * png_scale);
  }
  if (depth.width != width || depth.height != height)
    fail_file(file, "depth is {}x{} but the view is {}x{}", depth.width, depth.height, width, height);
  return depth;
}

std::optional<Image> load_view_depth(const Scene& scene, const View& view, const std::string& folder) {
  const fs::path file = scene.root / folder / (view.name + ".npy");
  if (!fs::exists(file)) return std::nullopt;
  return read_depth_map(file, view.camera.K.width, view.camera.K.height);
}

namespace {

// A scene's COLMAP points, read once per scene folder and subsampled (a median needs few);
// the most recent scenes are kept, so a long scene list stays within a few tens of MB.
constexpr size_t kMaxPointsPerScene = 2000, kMaxCachedScenes = 512;

std::shared_ptr<const std::vector<Eigen::Vector3d>> scene_points(const Scene& scene) {
  static std::mutex mutex;
  static std::map<std::string, std::shared_ptr<const std::vector<Eigen::Vector3d>>> cache;
  static std::deque<std::string> insertion_order;
  const std::string key = scene.root.string();
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (auto it = cache.find(key); it != cache.end()) return it->second;
  }
  auto points = std::make_shared<std::vector<Eigen::Vector3d>>();
  const std::vector<Eigen::Vector3d> all = load_scene_points(scene);
  const size_t stride = std::max<size_t>(1, (all.size() + kMaxPointsPerScene - 1) / kMaxPointsPerScene);
  for (size_t k = 0; k < all.size(); k += stride) points->push_back(all[k]);
  std::lock_guard<std::mutex> lock(mutex);
  const auto [it, inserted] = cache.emplace(key, std::move(points));
  if (inserted) {
    insertion_order.push_back(key);
    if (insertion_order.size() > kMaxCachedScenes) {
      cache.erase(insertion_order.front());
      insertion_order.pop_front();
    }
  }
  return it->second;
}

double median(std::vector<double> values) {
  const auto mid = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace

Image points_depth(const std::vector<Eigen::Vector3d>& points, const Camera& camera) {
  Image depth(camera.K.width, camera.K.height, 1, 0.f);
  const Eigen::Matrix4d w2c = camera.w2c_opencv();
  for (const Eigen::Vector3d& p : points) {
    const std::optional<PixelOfPoint> hit = pixel_of_point(camera.K, w2c, p);
    if (!hit) continue;
    float& d = depth.at(hit->y, hit->x);
    if (d == 0 || hit->z < d) d = static_cast<float>(hit->z);
  }
  return depth;
}

std::vector<Eigen::Vector3d> scene_geometry_points(const Scene& scene, bool colmap, PointsOrigin* origin, int stride,
                                                   const std::vector<int>& triangulate_from) {
  auto say = [&](PointsSource kind, std::string description) {
    if (origin) *origin = {kind, std::move(description)};
  };
  std::vector<Eigen::Vector3d> points;
  int maps = 0;
  for (const View& view : scene.views) {
    const std::optional<Image> depth = load_view_depth(scene, view);
    if (!depth) continue;
    ++maps;
    const Rays rays = compute_rays(view.camera);
    for (int y = stride / 2; y < depth->height; y += stride)
      for (int x = stride / 2; x < depth->width; x += stride) {
        const float d = depth->at(y, x);
        if (!(d > 0) || !std::isfinite(d)) continue;
        const size_t i = 3 * (static_cast<size_t>(y) * depth->width + x);
        points.emplace_back(rays.origin[i] + d * rays.dir_unnorm[i], rays.origin[i + 1] + d * rays.dir_unnorm[i + 1],
                            rays.origin[i + 2] + d * rays.dir_unnorm[i + 2]);
      }
  }
  if (!points.empty()) {
    say(PointsSource::DepthMaps, fmt::format("{} views' depth maps ({} points)", maps, points.size()));
    return points;
  }
  if (colmap) {
    const auto sparse = scene_points(scene);
    if (!sparse->empty()) {
      say(PointsSource::Colmap, fmt::format("the COLMAP model's points ({} used)", sparse->size()));
      return *sparse;
    }
  }
  if (!triangulate_from.empty()) {
    std::shared_ptr<const PhotoPoints> photos;
    try {
      photos = cached_photo_points(scene, triangulate_from);
    } catch (const Error& e) {  // a neighbour's unreadable photo: the network's depth as it is
      spdlog::warn("no points triangulated from the photos: {}", e.what());
      say(PointsSource::None, fmt::format("none (triangulating the photos failed: {})", e.what()));
      return points;
    }
    if (!photos->points.empty()) {
      say(PointsSource::Photos,
          fmt::format("points triangulated from {} views' photos ({} points from {} matches, {:.1f} s)",
                      triangulate_from.size(), photos->points.size(), photos->matches, photos->seconds));
      return photos->points;
    }
  }
  say(PointsSource::None, "none");
  return points;
}

double typical_scene_depth(const Scene& scene, const Camera& reference, const std::vector<Camera>& cameras) {
  const Eigen::Matrix4d w2c = reference.w2c_opencv();
  const auto points = scene_points(scene);
  if (!points->empty()) {
    std::vector<double> depths;
    for (const Eigen::Vector3d& X : *points) {
      const double z = (w2c.block<1, 3>(2, 0) * X)(0) + w2c(2, 3);
      if (z > 0) depths.push_back(z);
    }
    // Most points should be in front of a camera of the same reconstruction.
    if (depths.size() * 2 > points->size()) return median(depths);
  }
  if (scene.near && scene.far && *scene.near > 0 && *scene.far >= *scene.near)
    return std::sqrt(*scene.near * *scene.far);

  // The point nearest (least squares) to all optical axes: sum (I - a a^T)(X - c) = 0.
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Camera& cam : cameras) {
    const Eigen::Vector3d axis = -cam.rotation().col(2).normalized();  // OpenGL: looks along -z
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - axis * axis.transpose();
    A += P;
    b += P * cam.center();
    mean += cam.center();
  }
  double spread = 0;
  if (!cameras.empty()) {
    mean /= static_cast<double>(cameras.size());
    for (const Camera& cam : cameras) spread = std::max(spread, (cam.center() - mean).norm());
  }
  if (cameras.size() >= 2) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
    // Nearly parallel axes (forward-facing captures) leave the system ill-conditioned.
    if (eig.eigenvalues().minCoeff() > 1e-3 * eig.eigenvalues().maxCoeff()) {
      const Eigen::Vector3d X = A.ldlt().solve(b);
      const double z = (w2c.block<1, 3>(2, 0) * X)(0) + w2c(2, 3);
      if (z > 0 && std::isfinite(z)) return z;
    }
  }
  return spread > 0 ? 2.0 * spread : 1.0;
}

}  // namespace ii
