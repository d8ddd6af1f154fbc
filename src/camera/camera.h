#pragma once
// Pinhole cameras in the official conventions: camera-to-world in OpenGL axes (x right,
// y up, z backward; the camera looks along -z), intrinsics in pixels with the principal
// point in continuous image coordinates (pixel centres at +0.5).
#include <array>
#include <optional>
#include <vector>

#include <Eigen/Core>

namespace ii {

struct Intrinsics {
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0;  // focal lengths in pixels
  double cx = 0, cy = 0;  // principal point

  // From full fields of view with a centred principal point.
  static Intrinsics from_fov(int width, int height, double fov_x, double fov_y);
  double fov_x() const;  // 2 atan(W / (2 fx))
  double fov_y() const;  // 2 atan(H / (2 fy))
};

// Lens distortion in OpenCV's coefficient order (k1, k2, p1, p2, k3); all zero = none.
struct Distortion {
  std::array<double, 5> coeffs{};
  bool any() const;
};

struct Camera {
  Intrinsics K;
  Eigen::Matrix4d c2w = Eigen::Matrix4d::Identity();  // OpenGL axes

  Eigen::Vector3d center() const { return c2w.block<3, 1>(0, 3); }
  Eigen::Matrix3d rotation() const { return c2w.block<3, 3>(0, 0); }
  // World-to-camera in OpenCV axes (x right, y down, z forward), as renderers want it.
  Eigen::Matrix4d w2c_opencv() const;

  // The official 20-number camera vector: c2w row-major (16), fov_x, fov_y, 0.5, 0.5.
  std::array<float, 20> official_vector() const;

  // The same camera for the image resized by (sx, sy) (e.g. new_width / old_width).
  Camera resized(int new_width, int new_height) const;
  // The same camera for the sub-image with top-left (x0, y0) and the given size.
  Camera cropped(int x0, int y0, int new_width, int new_height) const;
};

// Where a world point lands in a camera's picture: the pixel it falls in (column x, row y) and its
// camera z. nullopt when it is behind the camera or outside the picture. `w2c` is the camera's
// w2c_opencv(), computed once by callers that project many points.
struct PixelOfPoint {
  int x = 0, y = 0;
  double z = 0;
};
inline std::optional<PixelOfPoint> pixel_of_point(const Intrinsics& K, const Eigen::Matrix4d& w2c,
                                                  const Eigen::Vector3d& point) {
  const Eigen::Vector3d c = w2c.topLeftCorner<3, 3>() * point + w2c.topRightCorner<3, 1>();
  if (!(c.z() > 0)) return std::nullopt;
  const double u = K.fx * c.x() / c.z() + K.cx, v = K.fy * c.y() / c.z() + K.cy;
  if (!(u >= 0 && v >= 0 && u < K.width && v < K.height)) return std::nullopt;
  return PixelOfPoint{static_cast<int>(u), static_cast<int>(v), c.z()};
}

// Conversions between camera axis conventions of a camera-to-world matrix: OpenCV/COLMAP
// (y down, z forward) <-> OpenGL (y up, z backward) negate rotation columns 1 and 2.
Eigen::Matrix4d opencv_to_opengl(const Eigen::Matrix4d& c2w);
Eigen::Matrix4d opengl_to_opencv(const Eigen::Matrix4d& c2w);

// Per-pixel rays through pixel centres, row-major over (row, column), 3 floats each:
// `origin` = camera centre, `dir` = unit world direction, `dir_unnorm` = world direction
// whose camera-frame z is exactly -1 (so a point at z-depth t is origin + t * dir_unnorm).
struct Rays {
  int width = 0, height = 0;
  std::vector<float> origin, dir, dir_unnorm;  // each height*width*3
};
Rays compute_rays(const Camera& camera);

// Plücker coordinates [d, o x d] per pixel, channel-first: 6 x height x width.
std::vector<float> plucker_chw(const Rays& rays);

// Translation-only pose normalisation (official §5.1): centres are shifted by their mean
// and divided by the largest absolute coordinate, so all lie in [-1,1]^3. Rotations stay.
struct PoseNormalization {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double scale = 1.0;  // the official `cam_loc_scale`

  Camera apply(const Camera& camera) const;
  Eigen::Vector3d apply(const Eigen::Vector3d& point) const { return (point - mean) / scale; }
};
PoseNormalization fit_pose_normalization(const std::vector<Camera>& cameras);

}  // namespace ii
