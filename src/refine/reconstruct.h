#pragma once
// `reconstruct`: 3D Gaussian splatting of a whole posed capture, for captures the feed-forward
// network cannot predict whole (an orbit around an object). The trainer is refinement's
// (refine_gaussians: the same Adam, densification and loss), started from the capture's 3D
// points instead of a prediction, with 3DGS's rates and schedule.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/torch.h"
#include "data/preprocess.h"
#include "data/scene.h"
#include "eval/lpips.h"
#include "gaussians/gaussians.h"
#include "io/reconstruct_checkpoint.h"
#include "refine/refine.h"

namespace ii {

// 3DGS's schedule as fractions of a run of any length: positions from 1.6e-4 to 1.6e-6 of the
// camera extent, densification every 100 steps between 1/60 and half of the run, an opacity
// reset every tenth until then, SH raised one degree per tenth up to 3, a quarter and then half
// resolution for the first tenth and fifth (OpenSplat's and nerfstudio's downscales).
RefineOptions reconstruct_training(const RefineOptions& length);
// The same for a length as the command and Python take it: `steps` >= 0 that many steps, else
// `length` (fast, balanced, best or a time, as refine_setting reads it).
RefineOptions reconstruct_training(const std::string& length, int steps);

// The points the training starts from and where they came from.
struct StartPoints {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3f> colours;  // RGB in [0, 1]
  std::string source;                    // "COLMAP's points3D", "triangulated from the photos"
};

struct ReconstructOptions {
  RefineOptions training = reconstruct_training(RefineOptions{});
  int height = 0;  // rows of the working pictures; 0: the photos' own, at most 1600 on the long side
  // Every eighth view (0, 8, 16, ...: 3DGS's hold-out) left out of the training and scored.
  bool eval = false;
  int64_t max_splats = 1500000;  // densification stops growing at this many
  // Start from these Gaussians instead of the capture's points (a run continued, another
  // trainer's output); training.first_step says how far its run got.
  std::optional<GaussianSet> start;
  // Start from these points (start_points' answer, made already: --write-colmap wrote them).
  std::optional<StartPoints> points;
  // Scores LPIPS (VGG, as 3DGS's eval) beside PSNR and SSIM when given (its backbone is the user's).
  std::shared_ptr<const Lpips> lpips;
  torch::Device device = torch::kCPU;  // where to train
};


// The capture's COLMAP points where it has them, else points triangulated from its photos with
// its own cameras (data/photo_points.h); each coloured by the mean of the working pictures it
// projects into. Only points some view sees (in front of its camera, inside its picture). Error when
// fewer than 3 views are given, or when no view sees a point (views with no overlap, a wrong frame).
StartPoints start_points(const Scene& scene, const std::vector<PreparedView>& views);

// 3DGS's initial Gaussians: one per point, round, σ = the root mean square distance to its three
// nearest neighbours, opacity 0.1.
GaussianSet gaussians_from_points(const StartPoints& start);

// 3DGS's scene extent: 1.1 × the largest distance of a camera from their mean.
double camera_extent(const std::vector<PreparedView>& views);

// The capture's views at the working size (no crop), in its own frame.
std::vector<PreparedView> working_views(const std::vector<View>& views, int height);

struct ViewScore {
  std::string name;
  double psnr = 0, ssim = 0;
  std::optional<double> lpips;
};
// PSNR and SSIM of the Gaussians' render from each view against its picture (3DGS's eval: the
// whole picture, on `background`: the colour the Gaussians were trained in front of); LPIPS too
// with `lpips`.
std::vector<ViewScore> score_views(const GaussianSet& gaussians, const std::vector<PreparedView>& views,
                                   const std::array<float, 3>& background = {1.f, 1.f, 1.f},
                                   const Lpips* lpips = nullptr);

struct ReconstructResult {
  GaussianSet gaussians;  // the scene's frame, SH of the training's degree
  RefineResult training;
  std::string start_source;
  int64_t start_points = 0;
  std::vector<std::string> held_out;  // with eval
  std::vector<ViewScore> scores;      // the held-out views with eval, else the training views
  double mean_psnr = 0, mean_ssim = 0;
  std::optional<double> mean_lpips;
  double prepare_s = 0, start_s = 0, train_s = 0, score_s = 0;
};

ReconstructResult reconstruct_scene(const Scene& scene, const ReconstructOptions& options);

// LPIPS (VGG) with the backbone in `vgg_file`, else in $INSTAINPAINT_LPIPS_VGG; none without
// either (the heads from their default place). An Error names a file that is missing or wrong.
std::shared_ptr<const Lpips> lpips_scorer(const std::string& vgg_file);

// run.json's record of a reconstruction.
nlohmann::json reconstruct_report(const ReconstructResult& result, const ReconstructOptions& options);

// What a checkpoint is of: the training views' names, photo sizes and poses and the working
// height (from the scene's records: no photo decoded), so that --resume refuses a checkpoint of
// another scene, working size or hold-out.
std::string scene_fingerprint(const std::vector<View>& views, int height);

// The training views at their working size as a COLMAP folder (DIR/images/*.png, DIR/sparse/0
// with PINHOLE cameras, the views' poses and the start points with their colours): the same
// views and start for another trainer (OpenSplat, gsplat, 3DGS).
void write_colmap_start(const std::filesystem::path& dir, const std::vector<PreparedView>& views,
                        const StartPoints& start);

}  // namespace ii
