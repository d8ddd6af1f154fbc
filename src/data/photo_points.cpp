#include "data/photo_points.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "common/parallel.h"
#include "common/stopwatch.h"
#include "data/image_ops.h"
#include "data/masks.h"
#include "data/undistort.h"
#include "io/image.h"

namespace ii {

namespace {

constexpr double kPi = 3.14159265358979323846;

// A photo's SIFT features at the matching size.
struct Features {
  int width = 0, height = 0;
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
};

// A photo at the matching size with its camera there: the features' pixels in world terms.
struct PosedFeatures {
  std::shared_ptr<const Features> features;
  Camera camera;
  Eigen::Matrix<double, 3, 4> projection;  // K [R | t], OpenCV axes
};

PosedFeatures posed(const View& view, std::shared_ptr<const Features> features) {
  PosedFeatures p;
  p.camera = view.camera.resized(features->width, features->height);
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  K(0, 0) = p.camera.K.fx;
  K(1, 1) = p.camera.K.fy;
  K(0, 2) = p.camera.K.cx;
  K(1, 2) = p.camera.K.cy;
  p.projection = K * p.camera.w2c_opencv().topRows<3>();
  p.features = std::move(features);
  return p;
}

// What a photo's pixels depend on (its file, undistorted with its intrinsics) or, `posed`, also
// where they lie in the world (its pose): the keys of the caches below.
std::string view_key(const View& view, bool posed) {
  const Intrinsics& K = view.camera.K;
  std::string key = fmt::format("{}\n{} {} {} {} {} {}", view.image_path.string(), K.width, K.height, K.fx, K.fy, K.cx, K.cy);
  for (double c : view.distortion.coeffs) key += fmt::format(" {}", c);
  if (posed)
    for (int i = 0; i < 16; ++i) key += fmt::format(" {}", view.camera.c2w(i / 4, i % 4));
  return key;
}

Features detect(const View& view, const PhotoPointsOptions& options) {
  Image rgb = read_image_rgb(view.image_path);
  if (view.distortion.any()) rgb = undistort_image(rgb, view.camera.K, view.distortion);
  const int h = std::min(options.height, rgb.height);
  const int w = std::max(1, static_cast<int>(std::lround(static_cast<double>(rgb.width) * h / rgb.height)));
  const Image small = resize_area(rgb, w, h);
  cv::Mat grey(h, w, CV_8UC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float v = 0.299f * small.at(y, x, 0) + 0.587f * small.at(y, x, 1) + 0.114f * small.at(y, x, 2);
      grey.at<uint8_t>(y, x) = static_cast<uint8_t>(std::clamp(v * 255.f + 0.5f, 0.f, 255.f));
    }
  Features f;
  f.width = w;
  f.height = h;
  // Bytes, not floats: OpenCV rounds SIFT's values to bytes either way, and the cache holds 4x more.
  cv::SIFT::create(options.max_features, 3, 0.04, 10, 1.6, CV_8U)
      ->detectAndCompute(grey, cv::noArray(), f.keypoints, f.descriptors);
  return f;
}

// The most recent values made for a key, up to `capacity`: a value is made once while it is kept.
template <typename T>
class RecentValues {
 public:
  explicit RecentValues(size_t capacity) : capacity_(capacity) {}
  std::shared_ptr<const T> get(const std::string& key, const std::function<T()>& make) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& [k, value] : entries_)
        if (k == key) return value;
    }
    auto value = std::make_shared<const T>(make());  // outside the lock: other keys go on
    std::lock_guard<std::mutex> lock(mutex_);
    entries_.emplace_back(key, value);
    if (entries_.size() > capacity_) entries_.pop_front();
    return value;
  }

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::deque<std::pair<std::string, std::shared_ptr<const T>>> entries_;
};

// Photos' features by file and matching size: a server's edits of one scene match the same
// photos again and again, and it detects them all while the page is painted on
// (prepare_photo_points). 256 photos of 1,500 features: about 60 MB.
std::shared_ptr<const Features> cached_features(const View& view, const PhotoPointsOptions& options) {
  static RecentValues<Features> cache(256);
  return cache.get(fmt::format("{}\n{} {}", view_key(view, false), options.height, options.max_features),
                   [&] { return detect(view, options); });
}

// Our pixel coordinates put pixel centres at +0.5; OpenCV's at integers.
Eigen::Vector2d pixel(const cv::KeyPoint& k) { return {k.pt.x + 0.5, k.pt.y + 0.5}; }

// Linear triangulation (DLT) of one match.
Eigen::Vector3d triangulate(const Eigen::Matrix<double, 3, 4>& P1, const Eigen::Vector2d& a,
                            const Eigen::Matrix<double, 3, 4>& P2, const Eigen::Vector2d& b) {
  Eigen::Matrix4d A;
  A.row(0) = a.x() * P1.row(2) - P1.row(0);
  A.row(1) = a.y() * P1.row(2) - P1.row(1);
  A.row(2) = b.x() * P2.row(2) - P2.row(0);
  A.row(3) = b.y() * P2.row(2) - P2.row(1);
  const Eigen::Vector4d X = Eigen::JacobiSVD<Eigen::Matrix4d>(A, Eigen::ComputeFullV).matrixV().col(3);
  return X.head<3>() / X.w();
}

// The point's pixel in a view and whether it lies in front of it.
bool project(const Eigen::Matrix<double, 3, 4>& P, const Eigen::Vector3d& X, Eigen::Vector2d& uv) {
  const Eigen::Vector3d p = P * X.homogeneous();
  if (!(p.z() > 0)) return false;
  uv = p.head<2>() / p.z();
  return true;
}

void triangulate_pair(const PosedFeatures& a, const PosedFeatures& b, const PhotoPointsOptions& options,
                      PhotoPoints& out) {
  const Features &fa = *a.features, &fb = *b.features;
  if (fa.descriptors.empty() || fb.descriptors.empty() || fb.keypoints.size() < 2) return;
  // Matched as floats: OpenCV's L2 distance of bytes has no vector path (3-4x slower).
  cv::Mat da, db;
  fa.descriptors.convertTo(da, CV_32F);
  fb.descriptors.convertTo(db, CV_32F);
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher(cv::NORM_L2).knnMatch(da, db, knn, 2);
  ++out.pairs;
  const double min_sin = std::sin(options.min_angle_deg * kPi / 180.0);
  const Eigen::Vector3d ca = a.camera.center(), cb = b.camera.center();
  for (const std::vector<cv::DMatch>& m : knn) {
    if (m.size() < 2 || m[0].distance > options.ratio * m[1].distance) continue;
    ++out.matches;
    const Eigen::Vector2d pa = pixel(fa.keypoints[static_cast<size_t>(m[0].queryIdx)]);
    const Eigen::Vector2d pb = pixel(fb.keypoints[static_cast<size_t>(m[0].trainIdx)]);
    const Eigen::Vector3d X = triangulate(a.projection, pa, b.projection, pb);
    if (!X.allFinite()) continue;
    Eigen::Vector2d ra, rb;
    if (!project(a.projection, X, ra) || !project(b.projection, X, rb)) continue;
    if ((ra - pa).norm() > options.max_reprojection_px || (rb - pb).norm() > options.max_reprojection_px) continue;
    const Eigen::Vector3d ray_a = (X - ca).normalized(), ray_b = (X - cb).normalized();
    if (ray_a.cross(ray_b).norm() < min_sin) continue;
    out.points.push_back(X);
  }
}

Eigen::Vector3d forward(const Camera& c) { return -c.rotation().col(2); }  // OpenGL: the camera looks down -z

}  // namespace

std::vector<int> triangulation_neighbours(const Scene& scene, int view, int count, double max_view_angle_deg) {
  const Camera& c = scene.views.at(static_cast<size_t>(view)).camera;
  std::vector<Camera> cameras;
  for (const View& v : scene.views) cameras.push_back(v.camera);
  const double wanted = 0.1 * typical_scene_depth(scene, c, cameras);
  const double min_cos = std::cos(max_view_angle_deg * kPi / 180.0);
  std::vector<std::pair<double, int>> candidates;
  for (size_t j = 0; j < scene.views.size(); ++j) {
    if (static_cast<int>(j) == view) continue;
    const Camera& o = scene.views[j].camera;
    const double distance = (o.center() - c.center()).norm();
    if (!(distance > 0) || forward(o).dot(forward(c)) < min_cos) continue;
    candidates.emplace_back(std::abs(std::log(distance / wanted)), static_cast<int>(j));
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<int> out;
  for (size_t k = 0; k < candidates.size() && static_cast<int>(out.size()) < count; ++k)
    out.push_back(candidates[k].second);
  return out;
}

namespace {

// The features of each of `views` (indices into scene.views), one photo per thread: decoding and
// the image pyramid's first levels are serial work.
std::map<int, PosedFeatures> features_of(const Scene& scene, const std::set<int>& views,
                                         const PhotoPointsOptions& options) {
  std::vector<int> list(views.begin(), views.end());
  std::vector<std::shared_ptr<const Features>> found(list.size());
  parallel_dynamic(static_cast<int64_t>(list.size()), thread_plan().cores, [&](int64_t i) {
    found[static_cast<size_t>(i)] = cached_features(scene.views.at(static_cast<size_t>(list[static_cast<size_t>(i)])), options);
  });
  std::map<int, PosedFeatures> out;
  for (size_t i = 0; i < list.size(); ++i) out.emplace(list[i], posed(scene.views.at(static_cast<size_t>(list[i])), found[i]));
  return out;
}

}  // namespace

PhotoPoints triangulate_photo_points(const Scene& scene, const std::vector<int>& views, const PhotoPointsOptions& options) {
  const Stopwatch clock;
  PhotoPoints out;
  std::map<int, std::vector<int>> pairs;  // view -> neighbours
  std::set<int> photos;                   // every photo taking part
  for (int v : views) {
    pairs[v] = triangulation_neighbours(scene, v, options.neighbours, options.max_view_angle_deg);
    photos.insert(v);
    photos.insert(pairs[v].begin(), pairs[v].end());
  }
  const std::map<int, PosedFeatures> features = features_of(scene, photos, options);
  for (const auto& [v, neighbours] : pairs)
    for (int n : neighbours) triangulate_pair(features.at(v), features.at(n), options, out);
  out.seconds = clock.ms() / 1000.0;
  return out;
}

namespace {

// One view's points with its neighbours (the default options), by the keys of the view and of
// its neighbours: points of a set of views are their views' points one after the other (as
// triangulate_photo_points makes them), so a server triangulates each view once, while its page is
// painted on (prepare_photo_points), and every edit's context only gathers them. 1024 views.
std::shared_ptr<const PhotoPoints> cached_view_points(const Scene& scene, int view) {
  static RecentValues<PhotoPoints> cache(1024);
  const PhotoPointsOptions options;
  std::string key = view_key(scene.views.at(static_cast<size_t>(view)), true);
  for (int n : triangulation_neighbours(scene, view, options.neighbours, options.max_view_angle_deg))
    key += "\n" + view_key(scene.views.at(static_cast<size_t>(n)), true);
  return cache.get(key, [&] { return triangulate_photo_points(scene, {view}, options); });
}

// `views` and the neighbours they are matched with.
std::set<int> with_neighbours(const Scene& scene, const std::set<int>& views) {
  const PhotoPointsOptions options;
  std::set<int> photos = views;
  for (int v : views)
    for (int n : triangulation_neighbours(scene, v, options.neighbours, options.max_view_angle_deg)) photos.insert(n);
  return photos;
}

}  // namespace

std::shared_ptr<const PhotoPoints> cached_photo_points(const Scene& scene, const std::vector<int>& views) {
  const std::set<int> unique(views.begin(), views.end());
  features_of(scene, with_neighbours(scene, unique), PhotoPointsOptions{});  // every photo at once, one per thread
  auto all = std::make_shared<PhotoPoints>();
  for (int v : unique) {
    const auto own = cached_view_points(scene, v);
    all->points.insert(all->points.end(), own->points.begin(), own->points.end());
    all->pairs += own->pairs;
    all->matches += own->matches;
    all->seconds += own->seconds;
  }
  return all;
}

void prepare_photo_points(const Scene& scene, const std::vector<int>& views) {
  cached_photo_points(scene, views);
}

std::shared_ptr<const std::vector<std::vector<Eigen::Vector3d>>> photo_points_of_every_view(const Scene& scene) {
  using ByView = std::vector<std::vector<Eigen::Vector3d>>;
  static RecentValues<ByView> cache(1024);
  std::string key;
  for (const View& view : scene.views) key += view_key(view, true) + "\n";
  return cache.get(key, [&] {
    ByView by_view;
    for (size_t v = 0; v < scene.views.size(); ++v)
      by_view.push_back(cached_view_points(scene, static_cast<int>(v))->points);
    return by_view;
  });
}

}  // namespace ii
