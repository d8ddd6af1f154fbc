#pragma once
// From a video or a folder of unposed photos to a posed scene the readers load: frames picked
// (the sharpest of each stretch of a video), posed by COLMAP, undistorted to pinhole cameras,
// and moved into a frame that suits our cameras (centred, up = -y, scaled like LLFF scenes).
//
//   OUT/images/, OUT/sparse/   the scene (COLMAP layout, PINHOLE cameras)
//   OUT/capture.json           what was done: inputs, frames, registration, timings, transform
//   OUT/colmap/                COLMAP's work: frames as posed, database, colmap.log, raw model
#include <filesystem>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "data/scene.h"
#include "io/colmap.h"

namespace ii {

struct CaptureOptions {
  int frames = 100;                 // frames taken from a video (all images of a folder are used)
  int max_size = 1008;              // long side of the posed images, in pixels
  // auto (sequential for a video; for a folder sequential in name order, then the other pairs when
  // that leaves images unposed) | sequential | exhaustive
  std::string matcher = "auto";
  std::string colmap = "colmap";    // the colmap executable (PATH lookup unless it has a '/')
  std::filesystem::path compare;    // a posed scene of the same views: its poses against ours
                                    // go into capture.json as "compared_with" (compare_poses)
  // Called at the start of each stage: (stage number from 1, stage count, what it does).
  std::function<void(int, int, const std::string&)> on_stage;
  // About once a second during COLMAP: its step, items done, items, seconds left (< 0: unknown).
  std::function<void(const std::string&, int, int, double)> on_colmap_progress;
};

// Runs the whole capture; returns capture.json's content. Throws Error with one clear message
// (missing tools, unreadable input, too few images, too few registered).
nlohmann::json capture_scene(const std::filesystem::path& input, const std::filesystem::path& out,
                             const CaptureOptions& options = {});

// The similarity (x' = scale * rotation * (x - centre)) that centres a model on its points,
// turns the cameras' mean up direction to -y and makes the largest distance between two
// cameras 10 units, as in the LLFF scenes the official orbit (radius 4) was made for.
struct SceneFrame {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double scale = 1;
};
SceneFrame sensible_frame(const ColmapModel& model);
void apply_frame(ColmapModel& model, const SceneFrame& frame);

// A view's name (file stem) and world-to-camera pose (OpenCV axes).
struct NamedPose {
  std::string name;
  Eigen::Matrix4d w2c;
};
std::vector<NamedPose> poses_of(const ColmapModel& model);
// The views (test views too) of a scene in any format load_scene reads.
std::vector<NamedPose> poses_of_scene(const std::filesystem::path& scene_dir);
std::vector<NamedPose> poses_of_scene(const Scene& scene);

// Camera poses of `posed` against `reference` after the best similarity between their camera
// centres (views matched by name, else in name order, as the frames of a video made from the
// reference's images): rotation errors in degrees after the rotation that best aligns the
// orientations, position errors as a fraction of the largest distance between two reference
// cameras.
struct PoseComparison {
  int matched = 0;
  double median_rotation_deg = 0, max_rotation_deg = 0;
  double median_position = 0, max_position = 0;
};
PoseComparison compare_poses(const std::vector<NamedPose>& posed, const std::vector<NamedPose>& reference);
// capture.json's "compared_with" (and scene-info --compare's JSON): the comparison against `scene`.
nlohmann::json comparison_json(const PoseComparison& comparison, const std::string& scene);
// One line: "against SCENE (N views matched): rotation median ... of the camera spread".
std::string comparison_line(const nlohmann::json& compared_with);

}  // namespace ii
