#pragma once
// The whole object a selected part of it belongs to, without a segmentation network: in a render
// with its exact depth, the pixels joined to the part's through neighbours of like depth that
// stand above the level surface under the part (a table, a floor). A click grows over one colour;
// a many-coloured object (a vase with a green neck and a red cap, a can with a silver lid) is
// then taken whole, and the surface it stands on is not.
#include <optional>

#include <Eigen/Core>

#include "camera/camera.h"
#include "common/torch.h"
#include "io/image.h"

namespace ii {

// `depth` and `covered` (H, W; CPU) are the render's from `camera`; `part` (H, W bool) the part's
// pixels; `up` the scene's up. nullopt when no level surface lies under the part (nothing it
// stands on in view) or when the object found would hold half of what the camera sees (the
// part's surface runs on into the room): the caller keeps the part.
struct ObjectAboveSupport {
  Image mask;           // the object's pixels
  Eigen::Vector3d up;   // unit
  double above = 0;     // the object lies above this height along up (the surface's and a margin)
  // and between these camera depths: the part's, widened by its size (a translucent file's pixels
  // blend the object's depth with the wall's behind it; its splats there are not the object's)
  double nearest = 0, farthest = 0;
};
std::optional<ObjectAboveSupport> object_above_support(const Camera& camera, const torch::Tensor& depth,
                                                       const torch::Tensor& covered, const torch::Tensor& part,
                                                       const Eigen::Vector3d& up);

}  // namespace ii
