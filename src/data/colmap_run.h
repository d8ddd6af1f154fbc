#pragma once
// Posing an unposed image folder with the `colmap` command-line tool: feature extraction,
// matching, incremental mapping. The result is an ordinary COLMAP scene for
// load_colmap_scene().
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace ii {

struct ColmapRunOptions {
  std::string executable = "colmap";      // looked up on PATH unless it contains a '/'
  std::string image_folder = "images";    // relative to the scene folder
  std::string camera_model = "OPENCV";    // one the scene reader converts
  bool single_camera = true;              // one shared camera for all images (one phone/lens)
  // exhaustive (every pair) | sequential (each image with the next ones in name order: video
  // frames, photos taken in turn) | sequential+exhaustive (sequential; when that leaves images
  // unposed, the pairs it skipped too, and mapping again: COLMAP's matchers skip matched pairs).
  std::string matcher = "exhaustive";
  int sequential_overlap = 10;            // the next images each one is matched with (COLMAP's default 10)
  int max_features = 8192;                // SIFT features per image (COLMAP's default)
  std::vector<std::string> mapper_options;  // more `colmap mapper` arguments ("--Mapper.x", "1.4", ...)
  bool use_gpu = false;                   // SIFT on the GPU needs an OpenGL/CUDA context
  // About once a second while a step runs, from its log: the step ("features", "matching",
  // "mapping"), how many of its items are done and of how many, and the seconds it likely
  // still needs (negative while unknown).
  std::function<void(const std::string& step, int done, int total, double eta_s)> progress;
};

// The colmap executable's absolute path, or an empty path when it cannot be found.
std::filesystem::path find_colmap(const std::string& executable = "colmap");

// What a run did: the model folder with the most images (sparse/0 in the usual single-model
// case), how many images it holds, the matchers that ran, and each step's seconds.
struct ColmapRun {
  std::filesystem::path model;
  int registered = 0;
  std::vector<std::string> matchers;
  double features_s = 0, matching_s = 0, mapping_s = 0;
};

// Runs the steps in `scene_dir`, writing database.db, sparse/<k>/ and colmap.log there. Throws
// Error when colmap is not installed, when a step fails (with the end of its log), or when
// nothing was reconstructed.
ColmapRun run_colmap_steps(const std::filesystem::path& scene_dir, const ColmapRunOptions& options = {});
// The model folder of run_colmap_steps.
std::filesystem::path run_colmap(const std::filesystem::path& scene_dir, const ColmapRunOptions& options = {});

}  // namespace ii
