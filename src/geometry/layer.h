#pragma once
// What each step after the network returns. The network's own Gaussians (one per input pixel,
// GaussianMaps) come back untouched; the steps that move, replace or fade them (the depth
// alignment, the measured surface, the region surface, the floaters) each return a MapsLayer, the
// maps after it; the steps that add Gaussians (past the frames, behind depth edges, over the
// reference's region) each return a GeometryLayer. A prediction is the last maps' Gaussians, then
// the added layers in order.
#include <string>

#include <nlohmann/json.hpp>

#include "gaussians/gaussians.h"

namespace ii {

struct GeometryLayer {
  std::string name;       // the step's key under "geometry" in run.json and metrics.json
  GaussianSet gaussians;  // empty when the step is off or added none
  nlohmann::json record;  // what run.json and metrics.json record of the step
};

struct MapsLayer {
  std::string name;  // the step's key under "geometry" in run.json and metrics.json
  // The network's Gaussians after this step and those before it: the attributes the step wrote
  // are its own copies, the others the same tensors as the step's input (all of them when off).
  GaussianMaps maps;
  nlohmann::json record;  // what run.json and metrics.json record of the step
};

}  // namespace ii
