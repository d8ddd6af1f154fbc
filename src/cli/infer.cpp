// `instainpaint infer`: predict the inpainted scene's Gaussians from a few posed views.
#include <nlohmann/json.hpp>
#include <fmt/core.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <optional>

#include "cli/commands.h"
#include "cli/edit_options.h"
#include "cli/refine_options.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "common/files.h"
#include "common/stage_times.h"
#include "common/stopwatch.h"
#include "io/image.h"
#include "io/splat_file.h"
#include "model/default_model.h"
#include "predict/predictor.h"
#include "render/rasterizer.h"
#include "render/visualize.h"

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
  EditArgs edit;
  RefineArgs refine;
  bool keep_unrefined = false;
  bool normalized = false;  // splats in the network's pose-normalised frame (before: the only one)
  std::vector<std::string> splats = {"gaussians.ply"};
  RuntimeOptions runtime;
};

void run(const InferArgs& a) {
  if (a.keep_object && !a.reference.empty()) fail("--keep-object uses the reference's own photo: drop --reference");
  if (a.keep_object && !a.edit.view.empty()) fail("--keep-object masks nothing: drop --view and --mask");
  if (a.edit.mode == "insert" && a.reference.empty())
    fail("--mode insert needs --reference: the reference view's photo with the new object painted in");
  for (const std::string& name : a.splats) splat_format_of(name);  // a bad name fails before the work
  const Runtime runtime = apply_runtime_options(a.runtime);
  Stopwatch total;
  StageTimes stages;

  spdlog::info("[1/4] reading scene {}", a.scene_dir);
  const Scene scene = load_scene(a.scene_dir, a.scene);
  const std::optional<OneMask> edit = one_mask_request(a.edit, scene, a.runtime.precision);
  stages.lap("read scene");

  spdlog::info("[2/4] loading model {}", a.checkpoint.empty() ? kDefaultModelName : a.checkpoint);
  const Predictor predictor(a.checkpoint, runtime.device, runtime.precision);
  stages.merge(predictor.load_stages(), "load model: ");
  stages.restart_lap();

  SceneInputOptions opts;
  opts.context = a.context;
  opts.num_views = a.views;
  if (!a.reference.empty()) opts.reference = fs::path(a.reference);
  opts.preprocess.height = a.height;
  opts.keep_object = a.keep_object;
  apply_reference_options(a.edit, opts);
  nlohmann::json edit_report;
  if (edit) {
    spdlog::info("masks for every view from the region on {}", edit->view);
    const SceneMasks masks =
        masks_from_one(scene, *edit, [&]() -> const Predictor& { return predictor; }, opts, &stages);
    masks.apply_to(opts, *edit);
    edit_report = masks.describe(*edit);
    spdlog::info("depth from {}; {} region{}", masks.depth_source, masks.regions.size(),
                 masks.regions.size() == 1 ? "" : "s");
    stages.restart_lap();
  }
  spdlog::info("[3/4] running the {} model ({}, {}) on {} views at height {} ...", predictor.config().preset,
               precision_name(predictor.precision()), runtime.device.str(),
               a.context.empty() ? a.views : static_cast<int>(a.context.size()), a.height);
  const Prediction p = predictor.predict(scene, opts);
  stages.merge(p.stages);
  stages.restart_lap();  // the prediction's parts are timed above

  const fs::path out(a.out);
  // Written in the scene's frame (its cameras'), unless --normalized.
  auto in_frame = [&](const GaussianSet& g) { return a.normalized ? g : in_scene_frame(g, p.input.normalization); };
  GaussianSet gaussians = p.gaussians();
  nlohmann::json refine_report;
  const RefineOptions refine = refine_options(a.refine);
  if (refine_requested(refine)) {
    if (a.keep_unrefined) write_splat_ply(out / "gaussians-unrefined.ply", splats_from_gaussians(in_frame(gaussians)));
    spdlog::info("refining {} Gaussians for {} against every view", gaussians.size(), refine_length(refine));
    gaussians = refine_prediction(scene, p, opts, gaussians.to(render_device(runtime.device)), refine, refine_report);
    write_loss_chart(out, refine_report);
    refine_report["unrefined"] = a.keep_unrefined ? nlohmann::json("gaussians-unrefined.ply") : nlohmann::json();
    stages.lap("refine");
  }

  spdlog::info("[4/4] writing {}", a.out);
  const SplatCloud cloud = splats_from_gaussians(in_frame(gaussians));
  stages.lap("gaussians to splats (host)");
  nlohmann::json splat_files = nlohmann::json::array();
  for (const std::string& name : a.splats) {
    write_splats(out / name, cloud);
    splat_files.push_back(name);
    stages.lap("write " + name);
  }
  nlohmann::json depth_files = nlohmann::json::array();
  for (int64_t v = 0; v < p.maps().depth.size(1); ++v) {
    const std::string file = fmt::format("depth/{}_{}.png", v, p.input.views[v].name);
    write_png(out / file, depth_colours(p.maps().depth[0][v][0]));
    depth_files.push_back(file);
  }
  stages.lap("write depth pictures");

  const auto& shape = p.input.input.images.sizes();
  const PoseNormalization& norm = p.input.normalization;
  nlohmann::json run = {
      {"scene", scene.root.string()},
      {"format", scene.format},
      {"context", nlohmann::json::array()},
      {"reference", p.input.reference_source},
      {"inpainter", p.input.reference_inpainter},
      {"geometry", p.describe_geometry()},
      {"edit", edit_report},
      {"refine", refine_report},
      {"working_size", {shape[3], shape[2]}},
      {"model", predictor.describe()},
      {"precision", precision_name(predictor.precision())},
      {"device", runtime.device.str()},
      {"threads", torch::get_num_threads()},
      {"gaussians", cloud.size()},
      {"normalization", {{"mean", {norm.mean.x(), norm.mean.y(), norm.mean.z()}}, {"scale", norm.scale}}},
      {"frame", a.normalized ? "normalized: scene = normalized x scale + mean" : "scene"},
      {"outputs", {{"splats", splat_files}, {"depth", depth_files}}},
      {"stages", nlohmann::json()}};
  for (const auto& v : p.input.views) run["context"].push_back(v.name);
  run["stages"] = stages.to_json();
  run["total_ms"] = total.ms();
  write_file_atomic(out / "run.json", run.dump(2) + "\n");

  fmt::print("{} Gaussians from {} views ({}, {}), network {:.0f} ms, total {:.0f} ms\n", cloud.size(),
             p.input.views.size(), precision_name(predictor.precision()), runtime.device.str(), stages.ms("network"),
             total.ms());
  for (const std::string& name : a.splats) fmt::print("wrote {}\n", (out / name).string());
  fmt::print("wrote {}, depth/\n", (out / "run.json").string());
}

}  // namespace

void add_infer_command(CLI::App& app) {
  auto args = std::make_shared<InferArgs>();
  auto* cmd = app.add_subcommand("infer", "Predict 3D Gaussians of the scene without the object");
  add_scene_options(cmd, args->scene_dir, args->scene);
  cmd->add_option("--reference", args->reference,
                  "The reference view's photo with the object painted out by a 2D inpainter, at "
                  "the photo's size or the working size (default: painted by --inpainter)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--checkpoint", args->checkpoint,
                  kCheckpointHelp);
  cmd->add_option("--context", args->context, "Context views by name, reference first (default: automatic)")
      ->delimiter(',');
  cmd->add_option("--views", args->views, "Number of context views when chosen automatically")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  cmd->add_option("--height", args->height, "Working height in pixels (width follows the aspect ratio)")
      ->capture_default_str()
      ->check(CLI::Range(8, 4096));
  add_reference_options(cmd, args->edit);
  add_edit_options(cmd, args->edit);
  add_refine_options(cmd, args->refine);
  cmd->add_flag("--keep-unrefined", args->keep_unrefined,
                "With --refine: also write the feed-forward Gaussians (gaussians-unrefined.ply)");
  cmd->add_flag("--keep-object", args->keep_object,
                "Reconstruct the scene as captured, object included (no masks, no reference): a comparison "
                "for the inpainted result");
  cmd->add_flag("--normalized", args->normalized,
                "Write the splats in the network's pose-normalised frame (scene = normalized x scale + mean, "
                "run.json's normalization) instead of the scene's own, which its cameras and other tools use");
  cmd->add_option("--out", args->out, "Output folder")->capture_default_str();
  cmd->add_option("--splats", args->splats,
                  "Splat files to write in the output folder, the format following each name: .ply (standard "
                  "3DGS), .compressed.ply (SuperSplat), .spz (Niantic; about a tenth of the size), .sog (PlayCanvas)")
      ->delimiter(',')
      ->capture_default_str();
  add_runtime_options(cmd, args->runtime);
  cmd->footer(
      "Writes OUT/gaussians.ply (standard 3DGS PLY; --splats for others), OUT/depth/*.png and OUT/run.json.\n"
      "Examples:\n"
      "  remove (a mask in every view):  instainpaint infer --scene ../shared/data/statue --checkpoint release.pth "
      "--reference inpainted.png --out out/statue\n"
      "  remove (one mask):  instainpaint infer --scene SCENE --view IMG_2707 --mask region.png "
      "--reference inpainted.png\n"
      "  remove (a box around the object):  instainpaint infer --scene SCENE --view IMG_2707 --box 150,90,360,330\n"
      "  insert:  instainpaint infer --scene SCENE --mode insert --view IMG_2707 --mask region.png "
      "--reference with_new_object.png\n"
      "  compressed as well:  instainpaint infer --scene SCENE --splats gaussians.ply,gaussians.spz");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
