#pragma once
// Internal to src/synth: the pieces generate_scene() assembles (room, furniture, object,
// camera path) and the level-of-detail rule they share.
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "camera/camera.h"
#include "synth/surfels.h"

namespace ii::synth {

// Where Gaussians must be dense: a surface seen from z metres away by a camera with focal
// length f pixels gets spacing = z / f * pixels_per_gaussian, clamped to [min, max]; a
// surface no camera sees gets max_spacing (it must exist, but only for completeness).
class DetailMap {
 public:
  DetailMap(std::vector<Camera> cameras, double pixels_per_gaussian, double min_spacing, double max_spacing);
  // Spacing for a surface region represented by sample points.
  double spacing(const std::vector<Eigen::Vector3d>& samples) const;
  // Spacing for everything inside a sphere.
  double spacing_sphere(const Eigen::Vector3d& centre, double radius) const;
  double min_spacing() const { return min_; }

 private:
  double spacing_sphere_points(const std::vector<Eigen::Vector3d>& points, double radius) const;

  std::vector<Camera> cameras_;
  std::vector<Eigen::Matrix4d> w2c_;
  double pixels_;
  double min_, max_;
};

// The plan of a room, drawn before any Gaussian is placed.
struct RoomPlan {
  Eigen::Vector3d room_min, room_max;  // inner walls, floor at room_min.y() = 0
  Eigen::Vector3d object_base;         // where the object stands (top of its support)
  double object_footprint = 0.2;       // horizontal radius of the object
  double keep_out = 1.5;               // furniture stays farther than this from the object (x, z)
  int support = 0;                     // 0 floor, 1 round table, 2 square table, 3 pedestal
  double support_size = 0;             // half width / radius of the support's top
};

// The background: room surfaces, decorations, furniture and the object's support. Appends to
// `out`, records what it made in `description`, fills lighting.contacts.
void build_room(const RoomPlan& plan, const DetailMap& detail, Lighting& lighting, SynthRng& rng, GaussianBuilder& out,
                nlohmann::json& description);

// A random composition of primitives standing on `base`, about `height` tall and at most
// `footprint` wide in radius.
void build_procedural_object(const Eigen::Vector3d& base, double height, double footprint, const DetailMap& detail,
                             const Lighting& lighting, SynthRng& rng, GaussianBuilder& out,
                             nlohmann::json& description);

// A splat object normalised once per process (cached): upright (+y), standing on the origin
// (centred in x and z), height 1 (robust bounding box: 0.5 and 99.5 percentiles), floaters
// and nearly transparent splats dropped, SH reduced to RGB, opacities <= kMaxOpacity.
const GaussianSet& normalized_splat_object(const std::filesystem::path& path);
// The normalised object scaled to `height`, turned by `yaw` about +y and standing on `base`.
GaussianSet place_splat_object(const GaussianSet& normalized, const Eigen::Vector3d& base, double height, double yaw);

}  // namespace ii::synth
