#pragma once
// The whole object a selected part of it belongs to, without a segmentation network: in a render
// with its exact depth, the pixels joined to the part's through neighbours of like depth that
// stand above the level surface under the part (a table, a floor). A click grows over one colour;
// a many-coloured object (a vase with a green neck and a red cap, a can with a silver lid) is
// then taken whole, and the surface it stands on is not.
#include <cstdint>
#include <optional>
#include <unordered_set>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "camera/camera.h"
#include "common/torch.h"
#include "io/image.h"

namespace ii {

// `picture` is the render from `camera`, `depth` and `covered` (H, W) its depth and where it
// covers; `part` (H, W bool) the part's pixels; `up` the scene's up. nullopt when no level
// surface lies under the part (nothing it stands on in view) or when the object found would hold
// half of what the camera sees (the part's surface runs on into the room): the caller keeps the
// part.
struct ObjectAboveSupport {
  Image mask;           // the object's pixels
  Eigen::Vector3d up;   // unit
  double above = 0;     // the object lies above this height along up (the surface's and a margin)
  // and, seen from the camera at `eye`, within these camera depths or these distances along the
  // level surface (the part's, widened by the object's size)
  Eigen::Vector3d eye;
  std::pair<double, double> depths, reach;
  bool within_reach(const Eigen::Vector3d& p, double camera_depth) const;

  // Whether `p` lies under the object: between the surface's height and `deepest`, inside the
  // object's outline seen from above. No camera sees there (a vase hides the table under
  // it from every side), and a trained file puts the object's colours there too.
  bool under(const Eigen::Vector3d& p) const;
  // Whether `colour` (RGB in [0, 1]) is nearer one of the object's pixels' than one of the surface's
  // around it: under the object a trained file holds both, and the surface's may stay.
  bool coloured_like_it(const Eigen::Vector3f& colour) const;

  // The outline seen from above: cells of `cell` on the level plane (axes `across`, `along`).
  Eigen::Vector3d across, along;
  double cell = 1, deepest = 0;
  std::unordered_set<int64_t> footprint;
  std::vector<Eigen::Vector3f> object_colours, surface_colours;  // samples of each
};
std::optional<ObjectAboveSupport> object_above_support(const Camera& camera, const Image& picture,
                                                       const torch::Tensor& depth,
                                                       const torch::Tensor& covered, const torch::Tensor& part,
                                                       const Eigen::Vector3d& up);

}  // namespace ii
