#pragma once
// Camera paths for rendering videos and camera lists in a small JSON format.
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "camera/camera.h"

namespace ii {

struct NamedCamera {
  std::string name;
  Camera camera;
};

// The official video path (spec §5.6): `frames` poses on a circle of `radius` around
// `centre`, in the plane whose normal n is the mean viewing direction (-z) of `cameras`,
// with in-plane axes u = n x (0,0,1) (n x (1,0,0) when n is nearly (0,0,1)), v = n x u;
// pose k at angle 2 pi k / frames from u towards v. Every pose keeps the rotation of the
// camera of `cameras` nearest to the centre. The official run uses 72 frames, the
// `vis_centroid` camera's position as centre, radius 4 / cam_loc_scale in normalised
// units (4 scene units), 512 x 512 with fov_x = fov_y of the first target camera.
std::vector<Camera> orbit_path(const std::vector<Camera>& cameras, const Eigen::Vector3d& centre, double radius,
                               int frames, const Intrinsics& K);

// A smooth path through `keys` in order: positions on a Catmull-Rom spline (through every
// key), rotations by quaternion slerp between consecutive keys; `frames` poses from the
// first key to the last, evenly spaced in spline parameter.
std::vector<Camera> smooth_path(const std::vector<Camera>& keys, int frames, const Intrinsics& K);

// Around an object: `frames` poses on a circle at `distance` from `target` and
// `elevation_deg` above the plane normal to `up`, all looking at the target with `up` up.
std::vector<Camera> turntable_path(const Eigen::Vector3d& target, double distance, double elevation_deg,
                                   const Eigen::Vector3d& up, int frames, const Intrinsics& K);

// A turntable that keeps the sphere (centre, radius) in view: the distance at which the sphere
// fills the vertical field of view `fov_y` (radians); square pixels, `width` x `height`.
std::vector<Camera> turntable_around_sphere(const Eigen::Vector3d& centre, double radius, double fov_y,
                                            double elevation_deg, const Eigen::Vector3d& up, int frames, int width,
                                            int height);

// The official orbit's default centre (its `vis_centroid` camera, when no file names one): the
// position of the camera nearest to the mean camera position.
Eigen::Vector3d central_camera_position(const std::vector<Camera>& cameras);
// The official orbit radius: 4 scene units (4 / cam_loc_scale in normalised units).
constexpr double kOfficialOrbitRadius = 4.0;

// Square-pixel intrinsics with the vertical field of view `fov_y` (radians), centred.
Intrinsics intrinsics_fov_y(int width, int height, double fov_y);
// `camera` at another image size: unchanged when both are 0 or less; one of them given keeps
// the aspect ratio.
Camera resized_to(const Camera& camera, int width, int height);

// An OpenGL camera-to-world (x right, y up, looking along -z) at `eye` looking at `target`.
Eigen::Matrix4d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up);

// Camera list JSON, either {"cameras": [...]} or a bare list. Each camera:
//   "name"            optional (default: its index, zero-padded)
//   "width","height"  image size in pixels (required)
//   "fx","fy"         focal lengths in pixels, or "fov_x_deg"/"fov_y_deg" (one of them is
//                     enough: square pixels); "cx","cy" default to the image centre
//   "c2w"             4x4 (or 3x4) camera-to-world, nested rows, or "w2c" world-to-camera
//   "convention"      "opengl" (default: x right, y up, looking along -z) or "opencv"
//                     (y down, looking along +z); may also be given once at the top level.
// Errors name the file and the camera.
std::vector<NamedCamera> read_camera_json(const std::filesystem::path& path);
// One camera of that list: name, width, height, fx, fy, cx, cy and c2w (OpenGL axes, rows).
nlohmann::json camera_list_entry(const NamedCamera& camera);
// Writes {"convention": "opengl", "cameras": [...]} of camera_list_entry()s (atomic).
void write_camera_json(const std::filesystem::path& path, const std::vector<NamedCamera>& cameras);

}  // namespace ii
