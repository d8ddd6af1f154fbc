#include "camera/trajectory.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "common/files.h"

namespace ii {

namespace {

Camera make_camera(const Intrinsics& K, const Eigen::Matrix3d& R, const Eigen::Vector3d& position) {
  Camera c;
  c.K = K;
  c.c2w.setIdentity();
  c.c2w.block<3, 3>(0, 0) = R;
  c.c2w.block<3, 1>(0, 3) = position;
  return c;
}

void check_frames(int frames) {
  if (frames < 1) fail("camera path: need at least one frame, not {}", frames);
}

}  // namespace

Eigen::Matrix4d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up) {
  Eigen::Vector3d back = eye - target;
  if (back.norm() < 1e-12) back = Eigen::Vector3d::UnitZ();
  back.normalize();
  Eigen::Vector3d right = up.cross(back);
  if (right.norm() < 1e-9) right = Eigen::Vector3d::UnitX().cross(back);  // looking along `up`
  if (right.norm() < 1e-9) right = Eigen::Vector3d::UnitY().cross(back);
  right.normalize();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 1>(0, 0) = right;
  m.block<3, 1>(0, 1) = back.cross(right);
  m.block<3, 1>(0, 2) = back;
  m.block<3, 1>(0, 3) = eye;
  return m;
}

std::vector<Camera> orbit_path(const std::vector<Camera>& cameras, const Eigen::Vector3d& centre, double radius,
                               int frames, const Intrinsics& K) {
  check_frames(frames);
  if (cameras.empty()) fail("orbit path: needs the scene's cameras");
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (const Camera& c : cameras) n += -c.rotation().col(2);  // OpenGL cameras look along -z
  if (n.norm() < 1e-12) n = -cameras[0].rotation().col(2);
  n.normalize();
  Eigen::Vector3d u = n.cross(Eigen::Vector3d::UnitZ());
  if (u.norm() < 1e-6) u = n.cross(Eigen::Vector3d::UnitX());  // n is (nearly) the z axis
  u.normalize();
  const Eigen::Vector3d v = n.cross(u).normalized();

  size_t nearest = 0;
  for (size_t i = 1; i < cameras.size(); ++i)
    if ((cameras[i].center() - centre).norm() < (cameras[nearest].center() - centre).norm()) nearest = i;
  const Eigen::Matrix3d R = cameras[nearest].rotation();

  std::vector<Camera> out;
  for (int k = 0; k < frames; ++k) {
    const double a = 2.0 * M_PI * k / frames;
    out.push_back(make_camera(K, R, centre + radius * (std::cos(a) * u + std::sin(a) * v)));
  }
  return out;
}

std::vector<Camera> smooth_path(const std::vector<Camera>& keys, int frames, const Intrinsics& K) {
  check_frames(frames);
  if (keys.empty()) fail("smooth path: needs at least one camera");
  const int n = static_cast<int>(keys.size());
  std::vector<Eigen::Quaterniond> q;
  for (const Camera& c : keys) {
    Eigen::Quaterniond r(c.rotation());
    r.normalize();
    // Keep consecutive quaternions in one hemisphere so slerp takes the short way.
    if (!q.empty() && q.back().dot(r) < 0) r.coeffs() *= -1;
    q.push_back(r);
  }
  auto P = [&](int i) { return keys[std::clamp(i, 0, n - 1)].center(); };
  std::vector<Camera> out;
  for (int f = 0; f < frames; ++f) {
    const double s = frames == 1 ? 0.0 : double(f) * (n - 1) / (frames - 1);
    const int i = std::min(static_cast<int>(s), std::max(n - 2, 0));
    const double t = n == 1 ? 0.0 : s - i;
    // Uniform Catmull-Rom through P(i) and P(i+1); end tangents from repeated end points.
    const Eigen::Vector3d p0 = P(i - 1), p1 = P(i), p2 = P(i + 1), p3 = P(i + 2);
    const double t2 = t * t, t3 = t2 * t;
    const Eigen::Vector3d pos = 0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t2 +
                                       (-p0 + 3 * p1 - 3 * p2 + p3) * t3);
    const Eigen::Quaterniond r = n == 1 ? q[0] : q[i].slerp(t, q[std::min(i + 1, n - 1)]);
    out.push_back(make_camera(K, r.toRotationMatrix(), pos));
  }
  return out;
}

std::vector<Camera> turntable_path(const Eigen::Vector3d& target, double distance, double elevation_deg,
                                   const Eigen::Vector3d& up_in, int frames, const Intrinsics& K) {
  check_frames(frames);
  const Eigen::Vector3d up = up_in.normalized();
  Eigen::Vector3d a = up.cross(Eigen::Vector3d::UnitX());
  if (a.norm() < 1e-6) a = up.cross(Eigen::Vector3d::UnitZ());
  a.normalize();
  const Eigen::Vector3d b = up.cross(a).normalized();
  const double el = elevation_deg * M_PI / 180.0;
  std::vector<Camera> out;
  for (int k = 0; k < frames; ++k) {
    const double az = 2.0 * M_PI * k / frames;
    const Eigen::Vector3d dir = std::cos(el) * (std::cos(az) * b + std::sin(az) * a) + std::sin(el) * up;
    Camera c;
    c.K = K;
    c.c2w = look_at(target + distance * dir, target, up);
    out.push_back(c);
  }
  return out;
}

std::vector<Camera> turntable_around_sphere(const Eigen::Vector3d& centre, double radius, double fov_y,
                                            double elevation_deg, const Eigen::Vector3d& up, int frames, int width,
                                            int height) {
  const double distance = std::max(radius, 1e-6) / std::sin(fov_y / 2.0);
  return turntable_path(centre, distance, elevation_deg, up, frames, intrinsics_fov_y(width, height, fov_y));
}

Eigen::Vector3d central_camera_position(const std::vector<Camera>& cameras) {
  if (cameras.empty()) fail("central_camera_position: no cameras");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Camera& c : cameras) mean += c.center();
  mean /= double(cameras.size());
  Eigen::Vector3d centre = cameras[0].center();
  for (const Camera& c : cameras)
    if ((c.center() - mean).norm() < (centre - mean).norm()) centre = c.center();
  return centre;
}

Intrinsics intrinsics_fov_y(int width, int height, double fov_y) {
  Intrinsics K;
  K.width = width;
  K.height = height;
  K.fy = height / (2.0 * std::tan(fov_y / 2.0));
  K.fx = K.fy;
  K.cx = width / 2.0;
  K.cy = height / 2.0;
  return K;
}

Camera resized_to(const Camera& c, int width, int height) {
  if (width <= 0 && height <= 0) return c;
  int w = width, h = height;
  if (w <= 0) w = std::max(1, static_cast<int>(std::lround(double(c.K.width) * h / c.K.height)));
  if (h <= 0) h = std::max(1, static_cast<int>(std::lround(double(c.K.height) * w / c.K.width)));
  return c.resized(w, h);
}

namespace {

Eigen::Matrix4d read_matrix(const nlohmann::json& j, const std::filesystem::path& path, const std::string& what) {
  if (!j.is_array() || (j.size() != 3 && j.size() != 4))
    fail_file(path, "{}: must be a 4x4 or 3x4 array of rows", what);
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (size_t r = 0; r < j.size(); ++r) {
    if (!j[r].is_array() || j[r].size() != 4) fail_file(path, "{}: row {} must have 4 numbers", what, r);
    for (size_t c = 0; c < 4; ++c) {
      if (!j[r][c].is_number()) fail_file(path, "{}: row {} has a non-number", what, r);
      m(r, c) = j[r][c].get<double>();
    }
  }
  if (!m.allFinite()) fail_file(path, "{}: not finite", what);
  return m;
}

double number(const nlohmann::json& cam, const char* key, const std::filesystem::path& path, const std::string& what) {
  if (!cam[key].is_number()) fail_file(path, "{}: '{}' must be a number", what, key);
  const double v = cam[key].get<double>();
  if (!std::isfinite(v)) fail_file(path, "{}: '{}' is not finite", what, key);
  return v;
}

// An image side in pixels: a whole number, at most 2^20 (pixel counts stay far from overflow).
int image_side(const nlohmann::json& cam, const char* key, const std::filesystem::path& path, const std::string& what) {
  const double v = number(cam, key, path, what);
  if (!(v >= 1 && v <= (1 << 20) && v == std::floor(v)))
    fail_file(path, "{}: '{}' must be a whole number of pixels from 1 to {}, not {}", what, key, 1 << 20, v);
  return static_cast<int>(v);
}

}  // namespace

namespace {

std::vector<NamedCamera> parse_camera_json(const std::filesystem::path& path) {
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(read_file_text(path));
  } catch (const nlohmann::json::exception& e) {
    fail_file(path, "not valid JSON: {}", e.what());
  }
  std::string top_convention = "opengl";
  nlohmann::json list = root;
  if (root.is_object()) {
    if (root.contains("convention")) top_convention = root["convention"].get<std::string>();
    if (!root.contains("cameras")) fail_file(path, "expected a list of cameras or an object with \"cameras\"");
    list = root["cameras"];
  }
  if (!list.is_array() || list.empty()) fail_file(path, "\"cameras\" must be a non-empty list");

  std::vector<NamedCamera> out;
  for (size_t i = 0; i < list.size(); ++i) {
    const nlohmann::json& j = list[i];
    NamedCamera nc;
    nc.name = j.contains("name") ? j["name"].get<std::string>() : fmt::format("{:04d}", i);
    const std::string what = fmt::format("camera {} ('{}')", i, nc.name);
    if (!j.is_object()) fail_file(path, "{}: must be an object", what);
    Intrinsics& K = nc.camera.K;
    if (!j.contains("width") || !j.contains("height")) fail_file(path, "{}: needs \"width\" and \"height\"", what);
    K.width = image_side(j, "width", path, what);
    K.height = image_side(j, "height", path, what);
    auto focal_from_fov = [&](const char* key, int size) {
      const double deg = number(j, key, path, what);
      if (!(deg > 0 && deg < 180)) fail_file(path, "{}: '{}' must be in (0, 180) degrees", what, key);
      return size / (2.0 * std::tan(deg * M_PI / 360.0));
    };
    if (j.contains("fx")) K.fx = number(j, "fx", path, what);
    if (j.contains("fy")) K.fy = number(j, "fy", path, what);
    if (K.fx == 0 && j.contains("fov_x_deg")) K.fx = focal_from_fov("fov_x_deg", K.width);
    if (K.fy == 0 && j.contains("fov_y_deg")) K.fy = focal_from_fov("fov_y_deg", K.height);
    if (K.fx == 0) K.fx = K.fy;  // square pixels when only one is given
    if (K.fy == 0) K.fy = K.fx;
    if (!(K.fx > 0 && K.fy > 0)) fail_file(path, "{}: needs positive fx/fy or fov_x_deg/fov_y_deg", what);
    K.cx = j.contains("cx") ? number(j, "cx", path, what) : K.width / 2.0;
    K.cy = j.contains("cy") ? number(j, "cy", path, what) : K.height / 2.0;

    Eigen::Matrix4d c2w;
    if (j.contains("c2w")) {
      c2w = read_matrix(j["c2w"], path, what + " c2w");
    } else if (j.contains("w2c")) {
      const Eigen::Matrix4d w2c = read_matrix(j["w2c"], path, what + " w2c");
      if (std::abs(w2c.block<3, 3>(0, 0).determinant()) < 1e-12) fail_file(path, "{}: w2c is singular", what);
      c2w = w2c.inverse();
    } else {
      fail_file(path, "{}: needs \"c2w\" or \"w2c\"", what);
    }
    const std::string convention = j.contains("convention") ? j["convention"].get<std::string>() : top_convention;
    if (convention == "opencv")
      c2w = opencv_to_opengl(c2w);
    else if (convention != "opengl")
      fail_file(path, "{}: convention must be \"opengl\" or \"opencv\", not \"{}\"", what, convention);
    nc.camera.c2w = c2w;
    out.push_back(nc);
  }
  return out;
}

}  // namespace

std::vector<NamedCamera> read_camera_json(const std::filesystem::path& path) {
  try {
    return parse_camera_json(path);
  } catch (const nlohmann::json::exception& e) {
    fail_file(path, "unexpected JSON value: {}", e.what());  // e.g. a name that is not a string
  }
}

nlohmann::json camera_list_entry(const NamedCamera& camera) {
  const Camera& c = camera.camera;
  nlohmann::json m = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) m.push_back({c.c2w(r, 0), c.c2w(r, 1), c.c2w(r, 2), c.c2w(r, 3)});
  return {{"name", camera.name}, {"width", c.K.width}, {"height", c.K.height}, {"fx", c.K.fx},
          {"fy", c.K.fy},        {"cx", c.K.cx},       {"cy", c.K.cy},         {"c2w", m}};
}

void write_camera_json(const std::filesystem::path& path, const std::vector<NamedCamera>& cameras) {
  nlohmann::json list = nlohmann::json::array();
  for (const NamedCamera& nc : cameras) list.push_back(camera_list_entry(nc));
  const nlohmann::json root = {{"convention", "opengl"}, {"cameras", list}};
  write_file_atomic(path, root.dump(1) + "\n");
}

}  // namespace ii
