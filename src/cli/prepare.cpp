// `instainpaint prepare`: build the network's inputs for a scene and write a report of what
// was read and built (no network run). Useful to check a capture before inference.
#include <nlohmann/json.hpp>
#include <fmt/core.h>

#include <filesystem>
#include <optional>

#include "cli/commands.h"
#include "cli/edit_options.h"
#include "common/files.h"
#include "common/stopwatch.h"
#include "io/image.h"
#include "model/scene_input.h"
#include "tensor/image_tensor.h"

namespace ii::cli {

namespace fs = std::filesystem;

namespace {

struct PrepareArgs {
  std::string scene_dir;
  SceneOptions scene;
  std::vector<std::string> context;
  std::string reference;
  int views = 4;
  int height = 512;
  std::string out = "prepare-out";
  EditArgs edit;
  std::string checkpoint;
  RuntimeOptions runtime;
};

// The image channels exactly as the network sees them, mapped back to [0,1] for viewing.
Image encoder_view_image(const torch::Tensor& images, int v) {
  return tensor_to_image((images[v].narrow(0, 0, 3) + 1.0) * 0.5);
}

Image mask_image(const torch::Tensor& images, int v) { return tensor_to_image(images[v].narrow(0, 3, 1)); }

void run(const PrepareArgs& a) {
  Stopwatch total;
  Stopwatch watch;
  const Scene scene = load_scene(a.scene_dir, a.scene);
  const double read_ms = watch.lap();
  SceneInputOptions opts;
  opts.context = a.context;
  opts.num_views = a.views;
  if (!a.reference.empty()) opts.reference = fs::path(a.reference);
  opts.preprocess.height = a.height;
  apply_reference_options(a.edit, opts);
  const std::optional<OneMask> edit = one_mask_request(a.edit, scene, a.runtime.precision);
  LazyPredictor predictor(a.checkpoint, a.runtime);
  nlohmann::json edit_report;
  if (edit) {
    const SceneMasks masks = masks_from_one(scene, *edit, predictor.source(), opts);
    masks.apply_to(opts, *edit);
    edit_report = masks.describe(*edit);
  }
  const SceneInput si = prepare_scene_input(scene, opts);
  const double build_ms = watch.lap();

  const fs::path out(a.out);
  nlohmann::json report;
  report["scene"] = {{"root", scene.root.string()},
                     {"format", scene.format},
                     {"views", scene.views.size()},
                     {"test_views", scene.test_views.size()},
                     {"warnings", scene.warnings}};
  report["normalization"] = {{"mean", {si.normalization.mean.x(), si.normalization.mean.y(), si.normalization.mean.z()}},
                             {"scale", si.normalization.scale}};
  report["reference_source"] = si.reference_source;
  report["edit"] = edit_report;
  const auto& shape = si.input.images.sizes();
  report["input"] = {{"views", shape[0]}, {"height", shape[2]}, {"width", shape[3]},
                     {"tokens", shape[0] * (shape[2] / 8) * (shape[3] / 8)}};
  report["context"] = nlohmann::json::array();
  for (size_t v = 0; v < si.views.size(); ++v) {
    const auto cam = si.input.cameras[v];
    const float coverage = si.input.images[v][3].mean().item<float>();
    const std::string file = fmt::format("inputs/{}_{}.png", v, si.views[v].name);
    write_png(out / file, encoder_view_image(si.input.images, static_cast<int>(v)));
    write_png(out / fmt::format("inputs/{}_{}_mask.png", v, si.views[v].name),
              mask_image(si.input.images, static_cast<int>(v)));
    report["context"].push_back({{"name", si.views[v].name},
                                 {"role", v == 0 ? "reference" : "masked"},
                                 {"mask_coverage", coverage},
                                 {"camera_vector", std::vector<float>(cam.data_ptr<float>(), cam.data_ptr<float>() + 20)},
                                 {"preview", file}});
  }
  report["timings_ms"] = {{"read_scene", read_ms}, {"build_inputs", build_ms}, {"total", total.ms()}};
  write_file_atomic(out / "report.json", report.dump(2) + "\n");

  fmt::print("scene {} ({}): {} views, {} test views\n", scene.root.string(), scene.format,
             scene.views.size(), scene.test_views.size());
  fmt::print("context (reference first):");
  for (const auto& v : si.views) fmt::print(" {}", v.name);
  fmt::print("\ninput {} x 4 x {} x {} ({} tokens), reference from {}\n", shape[0], shape[2],
             shape[3], shape[0] * (shape[2] / 8) * (shape[3] / 8), si.reference_source);
  fmt::print("wrote {} and inputs/ previews ({:.0f} ms)\n", (out / "report.json").string(), total.ms());
}

}  // namespace

void add_prepare_command(CLI::App& app) {
  auto args = std::make_shared<PrepareArgs>();
  auto* cmd = app.add_subcommand("prepare", "Build the network inputs for a scene and write a report (no inference)");
  add_scene_options(cmd, args->scene_dir, args->scene);
  cmd->add_option("--context", args->context, "Context view names, reference first (default: automatic)")
      ->delimiter(',');
  cmd->add_option("--views", args->views, "Number of context views when chosen automatically")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  cmd->add_option("--reference", args->reference,
                  "2D-inpainted image of the reference view (default: painted by --inpainter)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--height", args->height, "Working height in pixels")->capture_default_str()->check(CLI::Range(8, 4096));
  add_reference_options(cmd, args->edit);
  add_edit_options(cmd, args->edit);
  cmd->add_option("--checkpoint", args->checkpoint,
                  "With --view/--mask and no other depth: the model that reconstructs the marked view's depth. " + kCheckpointHelp)
      ->check(CLI::ExistingFile);
  add_runtime_options(cmd, args->runtime);
  cmd->add_option("--out", args->out, "Output folder")->capture_default_str();
  cmd->footer("Example: instainpaint prepare --scene ../shared/data/statue --out prepare-out");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
