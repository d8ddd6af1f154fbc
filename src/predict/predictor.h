#pragma once
// The library's one path from a scene to Gaussians: load a model once, predict many times
// (the shape of llama.cpp's load-once, call-many API). It composes the scene's input and the
// network (src/model) with the geometry's steps after it (src/geometry). `infer` and `eval` call
// it; anything that edits, refines or serves scenes does too.
//
//   const Predictor predictor("release.pth", device, precision);   // reads and uploads the weights
//   SceneInputOptions input;                                       // context views, reference, masks
//   input.reference_image = inpainted;                            // in memory, or a file
//   const Prediction p = predictor.predict(scene, input);
//   render(p.gaussians(), camera);                                 // in the pose-normalised frame
#include <string>

#include <nlohmann/json.hpp>

#include "common/stage_times.h"
#include "data/masks.h"
#include "gaussians/gaussians.h"
#include "geometry/depth_alignment.h"
#include "geometry/layer.h"
#include "geometry/options.h"
#include "model/config.h"
#include "model/network.h"
#include "model/scene_input.h"

namespace ii {

// A prediction's options: the network's input (model/scene_input.h) and what the geometry does
// with its output (geometry/options.h).
struct SceneInputOptions : InputOptions {
  // What Predictor::predict does with the network's Gaussians before it returns them.
  GeometryOptions geometry;
};

struct Prediction {
  SceneInput input;   // what the network saw: context views (reference first), normalisation
  // The network's output as it came, (1, V, C, H, W) on the predictor's device, in the
  // pose-normalised frame: no step changes it.
  GaussianMaps network;
  // The steps that move, replace or fade the network's Gaussians, in this order and always all
  // four, each the maps after it (geometry/layer.h): "depth_alignment" (each view's depth moved onto
  // the scene's points, geometry/depth_alignment.h), "measured_surface" (geometry/measured_surface.h),
  // "region_surface" (the reference's region on the surface around it, geometry/region_surface.h),
  // "floaters" (what another view sees through, faded: geometry/floaters.h).
  std::vector<MapsLayer> corrections;
  // The network's Gaussians after every correction (`network` when there is none).
  const GaussianMaps& maps() const;
  // Where predict's time went: prepare_scene_input's stages, then "upload" and "network".
  StageTimes stages;

  // Typed results of the corrections that later steps and commands act on.
  PointsSource geometry_kind = PointsSource::None;     // the scene points' source (None when not aligned)
  MeasuredFrom measured_from = MeasuredFrom::nothing;  // where the measured surface's depth came from
  // The reference's pixels the region surface put on the surface (flat indices; refinement keeps
  // their splats as they are).
  torch::Tensor region_surface_pixels;

  // The steps' Gaussians beside the network's own, in this order and always all three, empty when
  // off: "frame_margin" (past the edges of each view's picture, geometry/frame_margin.h),
  // "behind_edges" (the far side of depth edges under the near side, geometry/behind_edges.h),
  // "region_cover" (flat splats over the reference's region, geometry/region_cover.h).
  std::vector<GeometryLayer> layers;
  // The Gaussians of the layer `name` (an Error naming the layers when there is none such).
  const GaussianSet& layer(const std::string& name) const;

  // What run.json and metrics.json record of the geometry: the depth alignment's record at the top,
  // then each other step's under its name.
  nlohmann::json describe_geometry() const;

  // One Gaussian per input pixel, rows in the official order (views of `maps()`), then each layer's.
  GaussianSet gaussians() const;
};

class Predictor {
 public:
  // Reads `checkpoint` (an official .pth or safetensors; "default" = the default model built into
  // the library; empty or "auto" = the cache's released checkpoint when there is one, else the
  // default model: model/default_model.h resolve_checkpoint) and moves it to `device`. Errors name the file and what does not fit.
  Predictor(const std::string& checkpoint, const torch::Device& device, Precision precision);

  // Prepares the scene's input as `options` say (context views, reference, masks), checks
  // that the model can take it, uploads it and runs the network without gradients.
  Prediction predict(const Scene& scene, const SceneInputOptions& options) const;

  const std::string& model_name() const { return model_name_; }  // the file, or the default model's name
  const std::string& format() const { return format_; }          // "pth", "safetensors", ...
  const ModelConfig& config() const { return network_.config(); }
  const torch::Device& device() const { return device_; }
  Precision precision() const { return precision_; }
  // {"checkpoint", "format", "config"} and on a CPU "cpu" (the instruction sets detected, the
  // network's kernels: model/cpu/dispatch.h): what run.json and metrics.json record of the model.
  nlohmann::json describe() const;
  // Where the constructor's time went: "read checkpoint", "network from checkpoint",
  // "weights to <device>" (a command adds them to its own stages).
  const StageTimes& load_stages() const { return load_stages_; }

 private:
  std::string checkpoint_;  // the file read ("" for the default model)
  std::string model_name_, format_;
  torch::Device device_;
  Precision precision_;
  StageTimes load_stages_;
  Network network_;
};

}  // namespace ii
