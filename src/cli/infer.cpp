// `instainpaint infer`: predict the inpainted scene's Gaussians from a few posed views.
#include <nlohmann/json.hpp>
#include <fmt/core.h>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>

#include "cli/commands.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "common/files.h"
#include "common/stopwatch.h"
#include "io/image.h"
#include "io/ply.h"
#include "model/checkpoint.h"
#include "model/default_model.h"
#include "model/device.h"
#include "model/inference.h"
#include "model/scene_input.h"

namespace ii::cli {

namespace fs = std::filesystem;

namespace {

struct InferArgs {
  std::string scene_dir;
  SceneOptions scene;
  std::vector<std::string> context;
  std::string reference;
  std::string checkpoint;
  std::string out = "infer-out";
  int views = 4;
  int height = 512;
  bool keep_object = false;
  RuntimeOptions runtime;
};

// Depth as a colour image (near = bright), normalised per view for viewing.
Image depth_colormap(const torch::Tensor& depth) {
  const torch::Tensor d = depth.to(torch::kCPU, torch::kFloat32).contiguous();
  const float lo = d.min().item<float>(), hi = d.max().item<float>();
  cv::Mat grey(static_cast<int>(d.size(0)), static_cast<int>(d.size(1)), CV_8UC1);
  const float* p = d.data_ptr<float>();
  for (int i = 0; i < grey.rows * grey.cols; ++i)
    grey.data[i] = static_cast<uint8_t>(255.f * (1.f - (p[i] - lo) / std::max(hi - lo, 1e-6f)));
  cv::Mat colour;
  cv::applyColorMap(grey, colour, cv::COLORMAP_INFERNO);
  Image out(grey.cols, grey.rows, 3);
  for (int i = 0; i < grey.rows * grey.cols; ++i)
    for (int c = 0; c < 3; ++c) out.pixels[i * 3 + c] = colour.data[i * 3 + (2 - c)] / 255.f;  // BGR
  return out;
}

void run(const InferArgs& a) {
  const Runtime runtime = apply_runtime_options(a.runtime);
  const Precision precision = runtime.precision;
  Stopwatch total, watch;
  nlohmann::json timings;

  spdlog::info("[1/4] reading scene {}", a.scene_dir);
  const Scene scene = load_scene(a.scene_dir, a.scene);
  timings["read_scene_ms"] = watch.lap();

  spdlog::info("[2/4] preparing {} input views at height {}", a.context.empty() ? a.views : (int)a.context.size(), a.height);
  SceneInputOptions opts;
  opts.context = a.context;
  opts.num_views = a.views;
  if (!a.reference.empty()) opts.reference = fs::path(a.reference);
  opts.preprocess.height = a.height;
  opts.keep_object = a.keep_object;
  if (a.keep_object && !a.reference.empty()) fail("--keep-object uses the reference's own photo: drop --reference");
  SceneInput si = prepare_scene_input(scene, opts);
  timings["prepare_inputs_ms"] = watch.lap();

  const std::string model_name = a.checkpoint.empty() ? kDefaultModelName : a.checkpoint;
  spdlog::info("[3/4] loading model {}", model_name);
  const Checkpoint ck = checkpoint_or_default(a.checkpoint);
  Network net = network_from_checkpoint(ck, model_name);
  check_model_fits_input(ck.config, si.input, model_name);
  net.to(runtime.device);
  upload_network_inputs(si.input, runtime.device);
  synchronize(runtime.device);
  timings["load_model_ms"] = watch.lap();

  const auto& shape = si.input.images.sizes();
  spdlog::info("[4/4] running the {} model ({}, {}) on {} x {} x {} ...", ck.config.preset,
               precision_name(precision), runtime.device.str(), shape[0], shape[2], shape[3]);
  const GaussianMaps maps = run_network(net, si.input, precision);
  synchronize(runtime.device);
  timings["network_ms"] = watch.lap();

  const fs::path out(a.out);
  const SplatCloud cloud = to_splat_cloud(maps);
  write_splat_ply(out / "gaussians.ply", cloud);
  nlohmann::json depth_files = nlohmann::json::array();
  for (int64_t v = 0; v < maps.depth.size(1); ++v) {
    const std::string file = fmt::format("depth/{}_{}.png", v, si.views[v].name);
    write_png(out / file, depth_colormap(maps.depth[0][v][0]));
    depth_files.push_back(file);
  }
  timings["write_outputs_ms"] = watch.lap();
  timings["total_ms"] = total.ms();

  nlohmann::json run = {
      {"scene", scene.root.string()},
      {"format", scene.format},
      {"context", nlohmann::json::array()},
      {"reference", si.reference_source},
      {"working_size", {shape[3], shape[2]}},
      {"model", {{"checkpoint", model_name}, {"format", ck.format}, {"config", ck.config.to_json()}}},
      {"precision", precision_name(precision)},
      {"device", runtime.device.str()},
      {"threads", torch::get_num_threads()},
      {"gaussians", cloud.size()},
      {"normalization", {{"mean", {si.normalization.mean.x(), si.normalization.mean.y(), si.normalization.mean.z()}},
                         {"scale", si.normalization.scale}}},
      {"outputs", {{"ply", "gaussians.ply"}, {"depth", depth_files}}},
      {"timings", timings}};
  for (const auto& v : si.views) run["context"].push_back(v.name);
  write_file_atomic(out / "run.json", run.dump(2) + "\n");

  fmt::print("{} Gaussians from {} views ({}, {}), network {:.0f} ms, total {:.0f} ms\n", cloud.size(),
             si.views.size(), precision_name(precision), runtime.device.str(), timings["network_ms"].get<double>(),
             total.ms());
  fmt::print("wrote {}, {}, depth/\n", (out / "gaussians.ply").string(), (out / "run.json").string());
}

}  // namespace

void add_infer_command(CLI::App& app) {
  auto args = std::make_shared<InferArgs>();
  auto* cmd = app.add_subcommand("infer", "Predict 3D Gaussians of the scene without the object");
  add_scene_options(cmd, args->scene_dir, args->scene);
  cmd->add_option("--reference", args->reference,
                  "The reference view's photo with the object painted out by a 2D inpainter, at "
                  "the photo's size or the working size (default: OpenCV Telea inpainting)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--checkpoint", args->checkpoint,
                  "Model weights: official .pth or safetensors (default: the small model built into instainpaint, "
                  "see models/MODEL_CARD.md; the released InstaInpaint checkpoint is far better)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--context", args->context, "Context views by name, reference first (default: automatic)")
      ->delimiter(',');
  cmd->add_option("--views", args->views, "Number of context views when chosen automatically")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  cmd->add_option("--height", args->height, "Working height in pixels (width follows the aspect ratio)")
      ->capture_default_str()
      ->check(CLI::Range(8, 4096));
  cmd->add_flag("--keep-object", args->keep_object,
                "Reconstruct the scene as captured, object included (no masks, no reference): a comparison "
                "for the inpainted result");
  cmd->add_option("--out", args->out, "Output folder")->capture_default_str();
  add_runtime_options(cmd, args->runtime);
  cmd->footer(
      "Writes OUT/gaussians.ply (standard 3DGS PLY), OUT/depth/*.png and OUT/run.json.\n"
      "Example: instainpaint infer --scene ../shared/data/statue --checkpoint release.pth "
      "--reference inpainted.png --out out/statue");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
