#include "predict/predictor.h"

#include <future>

#include "common/error.h"
#include "data/masks.h"
#include "model/checkpoint.h"
#include "model/cpu/dispatch.h"
#include "model/default_model.h"
#include "model/device.h"
#include "model/inference.h"

namespace ii {

Predictor::Predictor(const std::string& checkpoint, const torch::Device& device, Precision precision)
    : model_name_(checkpoint.empty() ? kDefaultModelName : checkpoint),
      device_(device),
      precision_(precision),
      network_([&] {
        // A GPU's context is made while the file is read; the weights are read where the file
        // is mapped and copied there once.
        std::future<void> device_ready = start_device(device);
        Checkpoint ck = checkpoint_or_default(checkpoint, /*map_weights=*/!device.is_cpu());
        format_ = ck.format;
        load_stages_.lap("read checkpoint");
        Network network = network_from_checkpoint(std::move(ck), model_name_);
        load_stages_.lap("network from checkpoint");
        if (device_ready.valid()) {
          device_ready.get();
          load_stages_.lap("wait for the device's context (made beside the reading)");
        }
        network.to(device);
        synchronize(device);
        load_stages_.lap("weights to " + device.str());
        return network;
      }()) {}

nlohmann::json Predictor::describe() const {
  nlohmann::json d = {{"checkpoint", model_name_}, {"format", format_}, {"config", config().to_json()}};
  if (device_.is_cpu())
    d["cpu"] = cpu_kernels::describe_cpu_kernels(precision_ == Precision::BFloat16 ? torch::kBFloat16 : torch::kFloat32);
  return d;
}

namespace {

struct ScenePoints {
  std::vector<Eigen::Vector3d> points;
  PointsOrigin origin;
};

ScenePoints gather_scene_points(const Scene& scene, DepthPoints which, const std::vector<int>& context) {
  ScenePoints out;
  const bool colmap = which == DepthPoints::any;
  const bool photos = which == DepthPoints::any || which == DepthPoints::photos;
  out.points = scene_geometry_points(scene, colmap, &out.origin, 8, photos ? context : std::vector<int>{});
  return out;
}

// Each view's Gaussians past the edges of its picture, less those another view sees through.
GeometryLayer frame_margin_layer(Prediction& p, const FrameMarginOptions& options) {
  GaussianSet beyond = gaussians_beyond_frame(p.maps, p.input.input, options);
  const int64_t continued = beyond.size();
  if (options.drop_seen_through)
    beyond = without_seen_through(beyond, p.maps, p.input.views, p.input.input.view_cameras);
  nlohmann::json record =
      describe_frame_margin(options, p.maps.depth.size(3), beyond.size(), continued - beyond.size());
  if (beyond.size() > 0) p.stages.lap("Gaussians past the frames");
  return {"frame_margin", std::move(beyond), std::move(record)};
}

// The far side of each view's depth edges under the near side, less what another view sees through.
GeometryLayer behind_edges_layer(Prediction& p, const BehindEdgesOptions& given) {
  const BehindEdgesOptions options =
      behind_edges_for(given, p.measured_from == MeasuredFrom::depth_maps);
  GaussianSet behind = gaussians_behind_edges(p.maps, p.input.input, p.input.views, options);
  const int64_t found = behind.size();
  behind = without_seen_through(behind, p.maps, p.input.views, p.input.input.view_cameras);
  nlohmann::json record = describe_behind_edges(options, p.maps.depth.size(3), behind.size(), found - behind.size());
  if (found > 0) p.stages.lap("Gaussians behind depth edges");
  return {"behind_edges", std::move(behind), std::move(record)};
}

// Flat splats over the reference's region.
GeometryLayer region_cover_layer(Prediction& p, const RegionCoverOptions& options) {
  GaussianSet cover = region_cover_gaussians(p.input.views.front(), p.input.input.view_cameras.front(),
                                             p.maps.depth[0][0][0], options, p.maps.xyz);
  nlohmann::json record = describe_region_cover(options, cover.size());
  if (cover.size() > 0) p.stages.lap("the region's cover");
  return {"region_cover", std::move(cover), std::move(record)};
}

// Whether a step of `geometry` changes the network's maps in place (the others add layers).
bool changes_the_maps(const GeometryOptions& geometry) {
  return geometry.align_depth != DepthPoints::none || geometry.floaters.fade < 1;
}

// The steps GeometryOptions names, on the network's output in `p`, in order; each recorded.
void after_the_network(Prediction& p, const Scene& scene, const SceneInputOptions& options,
                       std::future<ScenePoints>& points) {
  const GeometryOptions& geometry = options.geometry;
  if (geometry.align_depth != DepthPoints::none) {
    const ScenePoints gathered =
        points.valid() ? points.get() : gather_scene_points(scene, geometry.align_depth, p.input.context);
    p.stages.lap(points.valid() ? "the scene's points (waited)" : "the scene's points");
    p.geometry = gathered.origin.description;
    p.geometry_kind = gathered.origin.kind;
    p.depth_detail = geometry.depth_detail.detail;
    if (!gathered.points.empty())
      p.depth_alignment = align_depth_to_points(p.maps, p.input, gathered.points, geometry.depth_detail);
    p.stages.lap("align depth to the scene's points");
    const MeasuredDepth measured =
        measured_depth(scene, p.input, options.preprocess, p.maps, geometry.measured_surface);
    if (!measured.source.empty()) p.stages.lap("the measured depth (" + measured.source + ")");
    const MeasuredSurface surface = put_on_measured_surface(p.maps, p.input, measured, geometry.measured_surface);
    p.measured_surface = describe_measured_surface(geometry.measured_surface, surface);
    p.measured_from = surface.from;
    if (!p.measured_surface["views"].empty()) p.stages.lap("the measured surface");
    const RegionSurface region = put_region_on_surface(p.maps, p.input, measured,
                                                       geometry.measured_surface.mask_margin, geometry.region_surface);
    p.region_surface = describe_region_surface(geometry.region_surface, region);
    p.region_surface_pixels = region.pixels;
    if (region.gaussians > 0) p.stages.lap("the region on the surface around it");
  }
  const int64_t faded = fade_floaters(p.maps, p.input.views, p.input.input.view_cameras, geometry.floaters);
  p.floaters = describe_floaters(geometry.floaters, faded);
  if (geometry.floaters.fade < 1) p.stages.lap("fade floaters");
  p.layers = {frame_margin_layer(p, geometry.frame_margin),
              behind_edges_layer(p, geometry.behind_edges),
              region_cover_layer(p, geometry.region_cover)};
}

}  // namespace

Prediction Predictor::predict(const Scene& scene, const SceneInputOptions& options) const {
  Prediction p;
  p.input = prepare_scene_input(scene, options, &p.stages);
  check_model_fits_input(config(), p.input.input, model_name_);
  p.stages.restart_lap();
  // The scene's points are the CPU's work (files, features): on a GPU run they are gathered
  // while the network runs; on a CPU run after it, which then has every core.
  std::future<ScenePoints> points;
  if (options.geometry.align_depth != DepthPoints::none && !device_.is_cpu())
    points = std::async(std::launch::async, gather_scene_points, std::cref(scene), options.geometry.align_depth,
                        p.input.context);
  upload_network_inputs(p.input.input, device_);
  synchronize(device_);
  p.stages.lap("upload");
  p.network = run_network(network_, p.input.input, precision_);
  synchronize(device_);
  p.stages.lap("network");
  p.maps = p.network;
  if (changes_the_maps(options.geometry)) {
    p.maps = cloned(p.network);
    p.stages.lap("the network's maps kept");
  }
  after_the_network(p, scene, options, points);
  return p;
}

const GaussianSet& Prediction::layer(const std::string& name) const {
  std::string names;
  for (const GeometryLayer& l : layers) {
    if (l.name == name) return l.gaussians;
    names += (names.empty() ? "" : ", ") + l.name;
  }
  fail("prediction: no layer '{}' (it has: {})", name, names.empty() ? "none" : names);
}

GaussianSet Prediction::gaussians() const {
  GaussianSet all = gaussians_from_maps(maps);
  for (const GeometryLayer& l : layers)
    if (l.gaussians.size() > 0) all = joined(all, l.gaussians);
  return all;
}

nlohmann::json Prediction::describe_geometry() const {
  nlohmann::json views = nlohmann::json::array();
  for (const DepthAlignment& a : depth_alignment)
    views.push_back({{"view", a.view}, {"scale", a.scale}, {"points", a.points}, {"detail_mean", a.detail_mean}});
  nlohmann::json d = {{"source", geometry},
                      {"detail", depth_detail},
                      {"views", views},
                      {"floaters", floaters},
                      {"measured_surface", measured_surface},
                      {"region_surface", region_surface}};
  for (const GeometryLayer& l : layers) d[l.name] = l.record;
  return d;
}

}  // namespace ii
