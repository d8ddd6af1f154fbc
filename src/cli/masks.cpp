// `instainpaint masks`: a mask for every view of a scene from one region marked on one view.
#include <nlohmann/json.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <filesystem>
#include <limits>
#include <optional>

#include "cli/commands.h"
#include "cli/edit_options.h"
#include "common/files.h"
#include "common/stage_times.h"
#include "common/stopwatch.h"
#include "edit/scene_masks.h"
#include "io/image.h"

namespace ii::cli {

namespace fs = std::filesystem;

namespace {

struct MasksArgs {
  std::string scene_dir;
  SceneOptions scene;
  EditArgs edit;
  std::string checkpoint;
  int views = 4;
  int height = 512;
  std::string out = "masks-out";
  RuntimeOptions runtime;
};

void run(const MasksArgs& a) {
  Stopwatch total;
  const Scene scene = load_scene(a.scene_dir, a.scene);
  const OneMask request = *one_mask_request(a.edit, scene, a.runtime.precision);

  LazyPredictor predictor(a.checkpoint, a.runtime);
  SceneInputOptions input;
  input.num_views = a.views;
  input.preprocess.height = a.height;
  input.geometry = a.edit.geometry;
  StageTimes stages;
  const SceneMasks masks = masks_from_one(scene, request, predictor.source(), input, &stages);

  // Masks as the --masks option reads them; against the scene's own masks when it has them.
  const fs::path out(a.out);
  nlohmann::json views = nlohmann::json::array();
  double recall_sum = 0, precision_sum = 0;
  double worst_recall = std::numeric_limits<double>::infinity(), worst_precision = worst_recall;
  int compared = 0;
  for (const View& view : scene.views) {
    const Image& mask = masks.masks.at(view.name);
    write_png(out / (view.name + ".png"), mask);
    nlohmann::json entry = {{"name", view.name},
                            {"coverage", std::count(mask.pixels.begin(), mask.pixels.end(), 1.f) /
                                             static_cast<double>(mask.pixels.size())}};
    // A region marked by hand is its own mask; a click's or a box's marked view is made like the others.
    if (view.name != request.view || !request.clicks.empty() || request.box) {
      if (const auto truth = load_view_mask(view)) {
        const MaskAgreement agreement = mask_agreement(mask, *truth);
        entry["recall"] = agreement.recall;
        entry["precision"] = agreement.precision;
        recall_sum += agreement.recall;
        precision_sum += agreement.precision;
        worst_recall = std::min(worst_recall, agreement.recall);
        worst_precision = std::min(worst_precision, agreement.precision);
        ++compared;
      }
    }
    views.push_back(entry);
  }
  nlohmann::json report = masks.describe(request);
  report["scene"] = scene.root.string();
  report["views"] = views;
  if (compared > 0)
    report["agreement"] = {{"views", compared},
                           {"mean_recall", recall_sum / compared},
                           {"worst_recall", worst_recall},
                           {"mean_precision", precision_sum / compared},
                           {"worst_precision", worst_precision}};
  if (const Predictor* model = predictor.loaded()) report["model"] = model->describe();
  report["stages"] = stages.to_json();
  report["total_ms"] = total.ms();
  write_file_atomic(out / "masks.json", report.dump(2) + "\n");

  if (!masks.segmenter.is_null())
    fmt::print("clicked view's mask: {} ({}), mask {} of its {}, score {:.3f}, {} pixels\n",
               masks.segmenter["network"].get<std::string>(), masks.segmenter["file"].get<std::string>(),
               masks.segmenter["chosen"].get<int>() + 1, masks.segmenter["scores"].size(),
               masks.segmenter["scores"][masks.segmenter["chosen"].get<int>()].get<double>(),
               masks.segmenter["pixels"].get<int64_t>());
  else if (!masks.clicked_mask.empty())
    fmt::print("{} view's mask: {} (no --segmenter)\n", request.box ? "boxed" : "clicked", masks.clicked_mask);
  fmt::print("{} masks from view {} ({} region{}, depth: {})\n", scene.views.size(), request.view,
             masks.regions.size(), masks.regions.size() == 1 ? "" : "s", masks.depth_source);
  if (compared > 0)
    fmt::print("against the scene's own masks ({} views): recall mean {:.3f} worst {:.3f}, precision mean {:.3f} "
               "worst {:.3f}\n",
               compared, recall_sum / compared, worst_recall, precision_sum / compared, worst_precision);
  fmt::print("wrote {} masks and {} ({:.0f} ms)\n", scene.views.size(), (out / "masks.json").string(), total.ms());
}

}  // namespace

void add_masks_command(CLI::App& app) {
  auto args = std::make_shared<MasksArgs>();
  auto* cmd = app.add_subcommand("masks", "Make a mask for every view from one region marked (or one click) on one view");
  add_scene_options(cmd, args->scene_dir, args->scene);
  add_edit_options(cmd, args->edit);
  cmd->get_option("--view")->required();
  cmd->add_option("--checkpoint", args->checkpoint,
                  "The model whose reconstruction gives the depth when no --depth and no COLMAP points exist. " + kCheckpointHelp)
      ->check(CLI::ExistingFile);
  cmd->add_option("--views", args->views, "Context views of that reconstruction")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  add_align_depth_option(cmd, args->edit.geometry);
  cmd->add_option("--height", args->height, "Working height of that reconstruction")
      ->capture_default_str()
      ->check(CLI::Range(8, 4096));
  cmd->add_option("--out", args->out, "Output folder: <view>.png per view (for --masks) and masks.json")
      ->capture_default_str();
  add_runtime_options(cmd, args->runtime);
  cmd->footer(
      "When the scene has masks of its own, masks.json compares with them (recall, precision per view).\n"
      "Examples:\n"
      "  instainpaint masks --scene ../shared/data/statue --view IMG_2707 "
      "--mask ../shared/data/statue/images_2/label/IMG_2707.png --out masks\n"
      "  instainpaint masks --scene my_capture --view IMG_0001 --click 512,300 --out masks   # one click on the object\n"
      "  instainpaint masks --scene my_capture --view IMG_0001 --box 400,180,640,420 --out masks   # a box around it\n"
      "  instainpaint masks --scene my_capture --view IMG_0001 --click 512,300 --segmenter mobile-sam --out masks\n"
      "      # the clicked view's outline from MobileSAM (instainpaint models get mobile-sam)");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
