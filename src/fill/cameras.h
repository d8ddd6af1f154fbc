#pragma once
// The cameras a fill looks at its region with: the capture's own (or a camera list), those
// that see the region best; or, without any, cameras made around the region where nothing
// stands between them and it.
#include <optional>
#include <string>
#include <vector>

#include "camera/trajectory.h"
#include "fill/region.h"
#include "common/torch.h"
#include "common/stage_times.h"
#include "gaussians/gaussians.h"
#include "render/projection.h"

namespace ii {

struct FillCameraOptions {
  int views = 4;    // the reference and views - 1 others
  int height = 256;  // the working height (cameras are resized to it, width a multiple of 8)
  std::string reference;  // a given camera's name to take as the reference; empty: the best
  // Automatic cameras: the scene's up (zero: guessed, see choose_automatic_cameras).
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  // Renders read near the region alone draw only the splats that reach it (near_region); false:
  // every splat (the same pixels there, slower).
  bool cull = true;
};

// A camera's small render of the whole scene: where it saw the surfaces behind the region.
struct Sight {
  Camera camera;
  torch::Tensor depth, alpha;  // (H, W) float32 on the CPU
  // (H, W) bool: where the render is the whole scene's (a render culled to the region's window
  // lacks what lies in front outside it); undefined: everywhere.
  torch::Tensor complete;
  // The capture's own cameras alone (else undefined): the depth of the scene without the region
  // (H, W), and where that surface was seen (H, W bool): outside the region, or behind it where
  // another camera saw it from the same side. Nothing new may stand in front of it there.
  torch::Tensor kept_depth, kept_seen;
  torch::Tensor share;  // (H, W): the region's share of each pixel
};

// The depth tolerance of fill's visibility tests (geometry/visibility.h): a point within 3 % of the
// surface a camera drew is on it, one more than 3 % nearer hides it (synthetic rooms at 10 %: one
// hole 0.3 dB better, another 4.8 dB worse, more of it taken for seen).
constexpr double kSeenTolerance = 0.03;

// Where `sight` drew the scene (alpha above 0.5) and its render is the whole scene's.
torch::Tensor drawn_whole(const Sight& sight);

struct ChosenCameras {
  std::vector<NamedCamera> cameras;  // at the working size, the reference first
  std::vector<double> visible;       // the region's share of each one's pixels
  // More cameras that see the region (up to 8, at the working size): with the chosen ones, they
  // tell what of the surfaces behind the region was seen, and so is no hole; refinement looks
  // through them too.
  std::vector<NamedCamera> observers;
  // Every camera scored (64 pixels high): what they saw of the scene is no hole.
  std::vector<Sight> sights;
  // The cameras are the capture's own: what their renders show in front of the region is space
  // the photos saw empty (automatic cameras look from where no photo was taken).
  bool captured = false;
  // and go round it (90 degrees or more apart): what lies under the region, seen by none, is the
  // surface the capture's training continued there.
  bool round = false;
  std::string how;                   // "given (12 of 40 see the region)", "automatic (...)"
};

// The region as one flag per Gaussian, on `device` (where the scene's tensors are).
torch::Tensor region_flags(const RegionMask& region, const torch::Device& device);

// Which rows of `set` may draw near the region in `camera` (a flag per row): the pixels the
// `region`'s Gaussians cover, grown by a tenth of that window's size and 4 pixels; every row when the
// region is not in front of the camera. Renders that are read near the region alone draw only
// these (until 2026-11-27 every render projected every splat of the scene).
torch::Tensor near_region(const GaussianSet& set, const GaussianSet& region, const Camera& camera);
// That window (nullopt: the region is not in front of the camera).
std::optional<PixelWindow> region_window(const GaussianSet& region, const Camera& camera);

// The scene with the region white and everything else black, for rendering on black: a render's
// red channel is the region's share of each pixel, hidden where the rest of the scene is in front.
GaussianSet region_weight_set(const GaussianSet& scene, const torch::Tensor& in_region);

// Of `given` (at any size), the views that see most of the region (its share of the pixels of a
// small render where the rest of the scene may hide it), the reference first; an Error when
// none sees it. `stages` (optional) gets the time of the small renders ("choose cameras: scoring
// renders", with "...: culling" apart) and of the region's set.
ChosenCameras choose_given_cameras(const GaussianSet& scene, const RegionMask& region,
                                   const std::vector<NamedCamera>& given, const FillCameraOptions& options,
                                   StageTimes* stages = nullptr);

// Cameras on rings around the region's centre (every 30 degrees of azimuth, 10, 30 and 50
// degrees above the horizon, at 4 and 7 times the region's radius, 50-degree field of view),
// scored by how much of the region each sees unhidden (a camera behind a wall sees none of it);
// the best is the reference, the
// others the best ones at least 12 degrees apart within 60 degrees of it. `up`: the scene's,
// else the axis along which the scene is thinnest, pointing away from the bulk of splats below
// the region (objects rest on floors).
ChosenCameras choose_automatic_cameras(const GaussianSet& scene, const RegionMask& region,
                                       const FillCameraOptions& options, StageTimes* stages = nullptr);

// The scene's up for automatic cameras (see above), a unit vector.
Eigen::Vector3d guess_up(const SplatCloud& cloud, const RegionMask& region);

}  // namespace ii
