#pragma once
// Posing an unposed image folder with the `colmap` command-line tool: feature extraction,
// matching, incremental mapping. The result is an ordinary COLMAP scene for
// load_colmap_scene().
#include <filesystem>
#include <functional>
#include <string>

namespace ii {

struct ColmapRunOptions {
  std::string executable = "colmap";      // looked up on PATH unless it contains a '/'
  std::string image_folder = "images";    // relative to the scene folder
  std::string camera_model = "OPENCV";    // one the scene reader converts
  bool single_camera = true;              // one shared camera for all images (one phone/lens)
  std::string matcher = "exhaustive";     // exhaustive (small sets) | sequential (video frames)
  bool use_gpu = false;                   // SIFT on the GPU needs an OpenGL/CUDA context
  // About once a second while a step runs, from its log: the step ("features", "matching",
  // "mapping"), how many of its items are done and of how many, and the seconds it likely
  // still needs (negative while unknown).
  std::function<void(const std::string& step, int done, int total, double eta_s)> progress;
};

// The colmap executable's absolute path, or an empty path when it cannot be found.
std::filesystem::path find_colmap(const std::string& executable = "colmap");

// Runs the three steps in `scene_dir`, writing database.db, sparse/<k>/ and colmap.log
// there. Returns the folder of the reconstructed model with the most images (sparse/0 in
// the usual single-model case). Throws Error when colmap is not installed, when a step
// fails (with the end of its log), or when nothing was reconstructed.
std::filesystem::path run_colmap(const std::filesystem::path& scene_dir, const ColmapRunOptions& options = {});

}  // namespace ii
