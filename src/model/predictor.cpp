#include "model/predictor.h"

#include <cstdlib>
#include <future>

#include <spdlog/spdlog.h>

#include "common/stopwatch.h"
#include "data/masks.h"
#include "data/view_selection.h"

#include "model/checkpoint.h"
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
  return {{"checkpoint", model_name_}, {"format", format_}, {"config", config().to_json()}};
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

// The working size of the context's first view, before any photo is read: its camera's size.
std::optional<std::pair<int64_t, int64_t>> first_view_working_size(const Scene& scene,
                                                                   const SceneInputOptions& options) {
  try {
    std::optional<int> reference;
    if (!options.reference_view.empty()) reference = input_view_index(scene, options.reference_view);
    const std::vector<int> context = options.context.empty()
                                         ? select_context_views(scene, options.num_views, reference)
                                         : context_views_by_name(scene, options.context);
    const Intrinsics& K = scene.views.at(static_cast<size_t>(context.front())).camera.K;
    const WorkingSize size = working_size(K.width, K.height, options.preprocess);
    return std::make_pair(static_cast<int64_t>(size.height), static_cast<int64_t>(size.width));
  } catch (const std::exception&) {
    return std::nullopt;  // the preparation reports what is wrong
  }
}

// One view of zeros through the network at the working size: on a GPU the first forward pass
// in a process pays for what every later one reuses (CUDA loads each kernel at its first launch,
// cuBLAS and cuDNN make their handles and plans; eval: 418 ms against 225 ms warm). It runs on
// the thread that will run the real pass, as the libraries' handles are per thread.
void warm_up_network(const Network& network, int64_t height, int64_t width, Precision precision,
                     const torch::Device& device) {
  const auto on = torch::TensorOptions().device(device);
  ModelInput input;
  input.images = torch::zeros({1, network.config().image_channels, height, width}, on);
  input.plucker = torch::zeros({1, 6, height, width}, on);
  input.rays_o = torch::zeros({1, height, width, 3}, on);
  input.rays_d_un = torch::ones({1, height, width, 3}, on);
  run_network(network, input, precision);
  synchronize(device);
}

bool gpu_warm_up_enabled() {
  const char* v = std::getenv("INSTAINPAINT_GPU_WARM_UP");  // "0": off (measurements of the first call)
  return !(v && std::string(v) == "0");
}

}  // namespace

// On a GPU, the first prediction's input is prepared on another thread while this one warms
// the network up (warm_up_network); later predictions run as they are.
SceneInput Predictor::prepare_input(const Scene& scene, const SceneInputOptions& options, StageTimes& stages) const {
  const auto size = first_view_working_size(scene, options);
  if (device_.is_cpu() || warmed_up_.exchange(true) || !size || !gpu_warm_up_enabled())
    return prepare_scene_input(scene, options, &stages);
  std::future<SceneInput> prepared =
      std::async(std::launch::async, [&] { return prepare_scene_input(scene, options, &stages); });
  Stopwatch warm_up;
  try {
    warm_up_network(network_, size->first, size->second, precision_, device_);
  } catch (const std::exception& e) {
    spdlog::warn("the network's warm-up failed ({}); the prediction goes on without", e.what());
  }
  stages.add("network warm-up (beside preparing the input)", warm_up.ms(), /*behind=*/true);
  SceneInput input = prepared.get();
  stages.lap("wait for the network's warm-up");  // from the preparation's last stage: what it did not hide
  return input;
}

Prediction Predictor::predict(const Scene& scene, const SceneInputOptions& options) const {
  Prediction p;
  p.input = prepare_input(scene, options, p.stages);
  check_model_fits_input(config(), p.input.input, model_name_);
  p.stages.restart_lap();
  // The scene's points are the CPU's work (files, features): on a GPU run they are gathered
  // while the network runs; on a CPU run after it, which then has every core.
  std::future<ScenePoints> points;
  if (options.align_depth != DepthPoints::none && !device_.is_cpu())
    points = std::async(std::launch::async, gather_scene_points, std::cref(scene), options.align_depth,
                        p.input.context);
  upload_network_inputs(p.input.input, device_);
  synchronize(device_);
  p.stages.lap("upload");
  p.maps = run_network(network_, p.input.input, precision_);
  synchronize(device_);
  p.stages.lap("network");
  if (options.align_depth != DepthPoints::none) {
    const ScenePoints gathered =
        points.valid() ? points.get() : gather_scene_points(scene, options.align_depth, p.input.context);
    p.geometry = gathered.origin.description;
    p.geometry_kind = gathered.origin.kind;
    p.depth_detail = options.depth_detail.detail;
    if (!gathered.points.empty())
      p.depth_alignment = align_depth_to_points(p.maps, p.input, gathered.points, options.depth_detail);
    p.stages.lap("align depth to the scene's points");
  }
  p.beyond_frame = gaussians_beyond_frame(p.maps, p.input.input, options.frame_margin);
  p.frame_margin = describe_frame_margin(options.frame_margin, p.maps.depth.size(3), p.beyond_frame.size());
  if (p.beyond_frame.size() > 0) p.stages.lap("Gaussians past the frames");
  return p;
}

GaussianSet Prediction::gaussians() const {
  const GaussianSet per_pixel = gaussians_from_maps(maps);
  return beyond_frame.size() > 0 ? joined(per_pixel, beyond_frame) : per_pixel;
}

nlohmann::json Prediction::describe_geometry() const {
  nlohmann::json views = nlohmann::json::array();
  for (const DepthAlignment& a : depth_alignment)
    views.push_back({{"view", a.view}, {"scale", a.scale}, {"points", a.points}, {"detail_mean", a.detail_mean}});
  return {{"source", geometry}, {"detail", depth_detail}, {"views", views}, {"frame_margin", frame_margin}};
}

}  // namespace ii
