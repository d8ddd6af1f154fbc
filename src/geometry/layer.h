#pragma once
// A step's Gaussians beside the network's own: the steps after the network that add Gaussians
// (past the frames, behind depth edges, over the reference's region) each return one named layer,
// and a prediction is the network's Gaussians then its layers in order.
#include <string>

#include <nlohmann/json.hpp>

#include "gaussians/gaussians.h"

namespace ii {

struct GeometryLayer {
  std::string name;       // the step's key under "geometry" in run.json and metrics.json
  GaussianSet gaussians;  // empty when the step is off or added none
  nlohmann::json record;  // what run.json and metrics.json record of the step
};

}  // namespace ii
