#pragma once
// 3D points of a posed capture that carries none (an LLFF/SPIn-NeRF copy without sparse/, a
// nerfstudio capture without its point cloud): SIFT features of each given view matched with a
// few other views of the scene whose baseline suits the scene's depth, and triangulated with
// the scene's own cameras. The poses are known, so no bundle adjustment: a match is kept when
// the point lies in front of both cameras, reprojects within a pixel or two into both, and is
// seen under a useful angle. Enough for what the points are for here: the median ratio that
// scales a view's predicted depth (geometry/depth_alignment.h).
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "data/scene.h"

namespace ii {

struct PhotoPointsOptions {
  int height = 384;                  // rows the photos are matched at
  int neighbours = 2;                // views matched with each given view
  int max_features = 1500;           // SIFT features per photo
  double ratio = 0.75;               // Lowe's ratio test
  double max_reprojection_px = 1.5;  // at `height` rows, in both views
  double min_angle_deg = 1.0;        // the angle between the two rays at the point
  double max_view_angle_deg = 35.0;  // neighbours look about the same way
};

struct PhotoPoints {
  std::vector<Eigen::Vector3d> points;  // the scene's frame
  int pairs = 0;                        // view pairs matched
  int matches = 0;                      // matches before the checks
  double seconds = 0;
};

// The neighbours of `view` (an index into scene.views) that triangulate best: views looking
// about the same way whose distance is nearest to a tenth of the scene's typical depth in
// front of it (too near: the rays are almost parallel; too far: the photos differ).
std::vector<int> triangulation_neighbours(const Scene& scene, int view, int count, double max_view_angle_deg = 35.0);

// Points triangulated from each of `views` (indices into scene.views) with its neighbours.
// Unreadable photos throw an Error naming the file. Each photo's features are detected once per
// process (the last 256 photos are kept).
PhotoPoints triangulate_photo_points(const Scene& scene, const std::vector<int>& views,
                                     const PhotoPointsOptions& options = {});

// triangulate_photo_points with the default options, each view's points kept (the last 1024
// views asked, by file, intrinsics and pose of the view and its neighbours): the page's edits of
// one scene ask for a few views' points again and again. `seconds` is the views' triangulation
// time when they were made.
std::shared_ptr<const PhotoPoints> cached_photo_points(const Scene& scene, const std::vector<int>& views);

// Each view's own points (triangulated from its features with its neighbours, so that it sees
// them), for every view of the scene: a capture's sparse depth for training. Kept for the last
// 1024 scenes asked (by file, intrinsics and pose of every view).
std::shared_ptr<const std::vector<std::vector<Eigen::Vector3d>>> photo_points_of_every_view(const Scene& scene);

// Detects the features of `views` and triangulates their points now (a server, while its page is
// painted on), so that a later cached_photo_points of any of them only gathers them.
void prepare_photo_points(const Scene& scene, const std::vector<int>& views);

}  // namespace ii
