#include "predict/predictor.h"

#include <future>
#include <optional>

#include "common/error.h"
#include "data/masks.h"
#include "model/checkpoint.h"
#include "model/cpu/dispatch.h"
#include "model/default_model.h"
#include "model/device.h"
#include "model/inference.h"
#include "models/cache.h"

namespace ii {

Predictor::Predictor(const std::string& checkpoint_value, const torch::Device& device, Precision precision)
    : checkpoint_(resolve_checkpoint(checkpoint_value)),
      model_name_(checkpoint_.empty() ? kDefaultModelName : checkpoint_),
      device_(device),
      precision_(precision),
      network_([&] {
        // A GPU's context is made while the file is read; the weights are read where the file
        // is mapped and copied there once.
        std::future<void> device_ready = start_device(device);
        Checkpoint ck = checkpoint_or_default(checkpoint_, /*map_weights=*/!device.is_cpu());
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
  // The cache's file with its recorded SHA-256 (another file is named only: hashing a released
  // checkpoint would cost seconds a run).
  if (!checkpoint_.empty())
    if (const auto m = cached_model_of_file(checkpoint_)) d["checkpoint_file"] = {{"sha256", m->sha256}, {"from", "the cache"}, {"catalogue_name", m->name}};
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
  GaussianSet beyond = gaussians_beyond_frame(p.maps(), p.input.input, options);
  const int64_t continued = beyond.size();
  if (options.drop_seen_through)
    beyond = without_seen_through(beyond, p.maps(), p.input.views, p.input.input.view_cameras);
  nlohmann::json record =
      describe_frame_margin(options, p.maps().depth.size(3), beyond.size(), continued - beyond.size());
  if (beyond.size() > 0) p.stages.lap("Gaussians past the frames");
  return {"frame_margin", std::move(beyond), std::move(record)};
}

// The far side of each view's depth edges under the near side, less what another view sees through.
GeometryLayer behind_edges_layer(Prediction& p, const BehindEdgesOptions& given) {
  const BehindEdgesOptions options =
      behind_edges_for(given, p.measured_from == MeasuredFrom::depth_maps);
  GaussianSet behind = gaussians_behind_edges(p.maps(), p.input.input, p.input.views, options);
  const int64_t found = behind.size();
  behind = without_seen_through(behind, p.maps(), p.input.views, p.input.input.view_cameras);
  nlohmann::json record = describe_behind_edges(options, p.maps().depth.size(3), behind.size(), found - behind.size());
  if (found > 0) p.stages.lap("Gaussians behind depth edges");
  return {"behind_edges", std::move(behind), std::move(record)};
}

// Flat splats over the reference's region.
GeometryLayer region_cover_layer(Prediction& p, const RegionCoverOptions& options) {
  GaussianSet cover = region_cover_gaussians(p.input.views.front(), p.input.input.view_cameras.front(),
                                             p.maps().depth[0][0][0], options, p.maps().xyz);
  nlohmann::json record = describe_region_cover(options, cover.size());
  if (cover.size() > 0) p.stages.lap("the region's cover");
  return {"region_cover", std::move(cover), std::move(record)};
}

// Each context view's depth, positions and sizes moved onto the scene's points (the network's
// maps as they came when the scene has none or alignment is off).
MapsLayer depth_alignment_layer(Prediction& p, const GaussianMaps& network, const ScenePoints* gathered,
                                const DepthDetailOptions& options) {
  MapsLayer layer{"depth_alignment", network, {{"source", "off"}, {"detail", 0.0}, {"views", nlohmann::json::array()}}};
  if (!gathered) return layer;
  p.geometry_kind = gathered->origin.kind;
  layer.record["source"] = gathered->origin.description;
  layer.record["detail"] = options.detail;
  if (!gathered->points.empty()) {
    layer.maps = cloned(network, kDepthMap | kXyzMap | kScaleMap);
    for (const DepthAlignment& a : align_depth_to_points(layer.maps, p.input, gathered->points, options))
      layer.record["views"].push_back(
          {{"view", a.view}, {"scale", a.scale}, {"points", a.points}, {"detail_mean", a.detail_mean}});
  }
  p.stages.lap("align depth to the scene's points");
  return layer;
}

// Outside each view's mask, the measured surface in place of the network's Gaussians.
MapsLayer measured_surface_layer(Prediction& p, const GaussianMaps& aligned, const MeasuredDepth& measured,
                                 const MeasuredSurfaceOptions& options) {
  MapsLayer layer{"measured_surface", aligned, nlohmann::json::object()};
  if (!measured.source.empty()) p.stages.lap("the measured depth (" + measured.source + ")");
  if (options.opacity > 0 && !measured.depth.empty()) layer.maps = cloned(aligned);
  const MeasuredSurface surface = put_on_measured_surface(layer.maps, p.input, measured, options);
  layer.record = describe_measured_surface(options, surface);
  p.measured_from = surface.from;
  if (!surface.views.empty()) p.stages.lap("the measured surface");
  return layer;
}

// The reference's region on the measured surface around it.
MapsLayer region_surface_layer(Prediction& p, const GaussianMaps& surfaced, const MeasuredDepth& measured,
                               int mask_margin, const RegionSurfaceOptions& options) {
  MapsLayer layer{"region_surface", surfaced, nlohmann::json::object()};
  if (region_surface_may_apply(p.input, measured, options)) layer.maps = cloned(surfaced);
  const RegionSurface region = put_region_on_surface(layer.maps, p.input, measured, mask_margin, options);
  layer.record = describe_region_surface(options, region);
  p.region_surface_pixels = region.pixels;
  if (region.gaussians > 0) p.stages.lap("the region on the surface around it");
  return layer;
}

// What another view sees through, faded.
MapsLayer floaters_layer(Prediction& p, const GaussianMaps& before, const FloaterOptions& options) {
  MapsLayer layer{"floaters", options.fade < 1 ? cloned(before, kOpacityMap) : before, nlohmann::json::object()};
  const int64_t faded = fade_floaters(layer.maps, p.input.views, p.input.input.view_cameras, options);
  layer.record = describe_floaters(options, faded);
  if (options.fade < 1) p.stages.lap("fade floaters");
  return layer;
}

// The steps GeometryOptions names, on the network's output in `p`, in order; each a layer.
void after_the_network(Prediction& p, const Scene& scene, const SceneInputOptions& options,
                       std::future<ScenePoints>& points) {
  const GeometryOptions& geometry = options.geometry;
  const bool aligned = geometry.align_depth != DepthPoints::none;
  std::optional<ScenePoints> gathered;
  if (aligned) {
    gathered = points.valid() ? points.get() : gather_scene_points(scene, geometry.align_depth, p.input.context);
    p.stages.lap(points.valid() ? "the scene's points (waited)" : "the scene's points");
  }
  p.corrections = {depth_alignment_layer(p, p.network, gathered ? &*gathered : nullptr, geometry.depth_detail)};
  // The measured surface and the region on it need the aligned depth: off without the alignment.
  if (aligned) {
    const MeasuredDepth measured =
        measured_depth(scene, p.input, options.preprocess, p.maps(), geometry.measured_surface);
    p.corrections.push_back(measured_surface_layer(p, p.maps(), measured, geometry.measured_surface));
    p.corrections.push_back(region_surface_layer(p, p.maps(), measured, geometry.measured_surface.mask_margin,
                                                 geometry.region_surface));
  } else {
    p.corrections.push_back({"measured_surface", p.maps(), nlohmann::json::object()});
    p.corrections.push_back({"region_surface", p.maps(), nlohmann::json::object()});
  }
  p.corrections.push_back(floaters_layer(p, p.maps(), geometry.floaters));
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

const GaussianMaps& Prediction::maps() const { return corrections.empty() ? network : corrections.back().maps; }

GaussianSet Prediction::gaussians() const {
  GaussianSet all = gaussians_from_maps(maps());
  for (const GeometryLayer& l : layers)
    if (l.gaussians.size() > 0) all = joined(all, l.gaussians);
  return all;
}

nlohmann::json Prediction::describe_geometry() const {
  nlohmann::json d = nlohmann::json::object();
  for (const MapsLayer& l : corrections) {
    if (l.name == "depth_alignment")
      d.update(l.record);  // at the top, as run.json has had it since before the other steps
    else
      d[l.name] = l.record;
  }
  for (const GeometryLayer& l : layers) d[l.name] = l.record;
  return d;
}

}  // namespace ii
