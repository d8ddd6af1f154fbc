#pragma once
// Writes a synthetic scene in the LLFF / SPIn-NeRF layout every scene reader of the project
// reads (data/scene_readers.h), plus the ground truth the readers ignore:
//
//   poses_bounds.npy         LLFF rows in name-sorted order (test views first), H, W, f at
//                            `downscale` x the written size (as SPIn-NeRF's images_4 scenes)
//   images_<K>/test_NNN.png  object-free test views (sort before view_*: SPIn-NeRF's rule)
//   images_<K>/view_NNN.png  training views with the object, in camera-path order
//   images_<K>/label/        object masks of the training views, PNG 0/255
//   images_<K>/test_label/   object masks of the test views (where the object would be)
//   clean/<name>.png         object-free image of every view (exact removal ground truth)
//   depth/<name>.npy         float32 (H, W) expected camera z (metres, the scene's units) of
//                            the image in images_<K>/; 0 where nothing was hit (the format
//                            data/masks.h load_view_depth() reads)
//   depth_clean/<name>.npy   the same for clean/<name>.png (depth supervision in training)
//   reference.png            object-free image of the reference view, degraded if asked
//   cameras.json             every camera (camera/trajectory.h camera-list format)
//   synth.json               seed, options, names, reference, context views, mask rule, ...
//   background.ply, object.ply  the Gaussians (only with save_gaussians)
//   scene.ply                the room as a splat scene fitted to the training views could hold
//                            it (only with save_gaussians): the object, and the background
//                            splats that some training view sees (those it hides in every view
//                            are not there, as under an object in a capture)
//
// Task insert (`task`): the same room the other way round, as ground truth for object
// insertion. The training views show the room without the object, their label/ masks mark
// where it will appear; reference.png is the reference view with the object (the edited
// photo); test views, clean/ and depth_clean/ show the room with it (the edit's truth); depth/
// is the depth of the images in images_<K>/; original/ holds the test views without the object
// (what the scene looks like when nothing is inserted).
//
// The scene is written to "<dir>.partial" and renamed to `dir` when complete.
#include <array>
#include <filesystem>
#include <functional>
#include <string>

#include "synth/synth_scene.h"
#include "synth/synth_views.h"

namespace ii::synth {

enum class SynthTask { remove, insert };
// "remove" | "insert"; throws Error naming `what` otherwise.
SynthTask parse_synth_task(const std::string& text, const std::string& what = "--task");
std::string to_string(SynthTask task);

struct SynthWriteOptions {
  SynthTask task = SynthTask::remove;
  Degradation degrade = Degradation::none;  // applied to reference.png only
  int downscale = 4;                        // the K of images_K
  bool save_gaussians = false;
  bool write_depth = true;                            // depth/, depth_clean/ (float32: the largest part of a scene)
  nlohmann::json generator;                           // recorded in synth.json (e.g. the options used)
  std::function<void(int done, int total)> progress;  // after each view
};

struct SynthWriteSummary {
  int views = 0;
  int test_views = 0;
  std::string reference;
  std::string degradation;     // the one applied (mixed resolved)
  double object_fraction = 0;  // mean fraction of training-view pixels inside the mask
};

// One LLFF row: the 3x5 matrix [R | t | (H, W, f)] row-major with rotation columns (down,
// right, back), H, W, f at `downscale` x the camera's size, then near and far.
std::array<double, 17> llff_pose_row(const Camera& camera, int downscale, double near, double far);

// Writes `scene` to `dir`. An existing `dir` is replaced only if it is an earlier synthetic
// scene (has synth.json) or empty; anything else is an error.
SynthWriteSummary write_synth_scene(const SynthScene& scene, const std::filesystem::path& dir,
                                    const SynthWriteOptions& options);

// The synth.json of a written scene, checked to be one (Error naming the file otherwise).
nlohmann::json read_synth_json(const std::filesystem::path& scene_dir);

}  // namespace ii::synth
