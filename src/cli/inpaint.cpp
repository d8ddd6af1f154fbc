// `instainpaint inpaint`: one photo's region painted by a 2D inpainter (LaMa, or a classical one).
#include <fmt/core.h>

#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/edit_options.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "common/stage_times.h"
#include "data/scene.h"
#include "inpaint/lama_inpainter.h"
#include "io/image.h"

namespace ii::cli {

namespace {

struct InpaintArgs {
  std::string inpainter, image, mask, out = "inpainted.png";
  bool json = false, whole_photo = false;
  int repeat = 1;
  RuntimeOptions runtime;
};

void run(const InpaintArgs& args) {
  apply_runtime_options(args.runtime);
  StageTimes stages;
  LamaOptions lama;
  lama.whole_photo = args.whole_photo;
  lama.precision = args.runtime.precision;
  lama.device = args.runtime.device;
  const Inpainter inpainter =
      stages.time("read inpainter", [&] { return inpainter_from_flag(args.inpainter, "ns", lama); });
  const Image photo = stages.time("read photo", [&] { return read_image_rgb(args.image); });
  // As the scene readers take it: a mask a few pixels off (SPIn-NeRF's 1008x576 of 1008x567 photos) resized.
  const Image mask = stages.time("read mask", [&] {
    return mask_at_image_size(read_mask(args.mask), photo.width, photo.height, args.mask);
  });
  Image painted;
  for (int i = 0; i < args.repeat; ++i) painted = stages.time("paint", [&] { return inpainter.paint(photo, mask); });
  stages.time("write", [&] { write_png(args.out, painted); });
  int64_t pixels = 0;
  for (float v : mask.pixels) pixels += v > 0.5f;
  const nlohmann::json summary = {{"inpainter", inpainter.describe()}, {"out", args.out}, {"region_pixels", pixels},
                                  {"width", photo.width}, {"height", photo.height}, {"stages", stages.to_json()}};
  if (args.json) {
    fmt::print("{}\n", summary.dump(2));
    return;
  }
  fmt::print("{}: {} pixels of {}x{} painted by {} -> {}\n", args.image, pixels, photo.width, photo.height,
             inpainter.learned ? summary["inpainter"]["network"].get<std::string>() : inpainter.name(), args.out);
  for (const StageTimes::Stage& st : stages.stages())
    fmt::print("  {:<16} {:8.1f} ms{}\n", st.name, st.ms / std::max(1, st.calls),
               st.calls > 1 ? fmt::format(" (mean of {})", st.calls) : "");
}

}  // namespace

void add_inpaint_command(CLI::App& app) {
  auto args = std::make_shared<InpaintArgs>();
  auto* cmd = app.add_subcommand("inpaint", "Paint a photo's region with LaMa (or a classical 2D inpainter)");
  cmd->add_option("--inpainter", args->inpainter, kInpainterHelp + std::string("ns"));
  cmd->add_option("--image", args->image, "The photo")->required()->check(CLI::ExistingFile);
  cmd->add_option("--mask", args->mask, "The region (white = paint it), at the photo's size")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "The painted photo (PNG)")->capture_default_str();
  cmd->add_option("--repeat", args->repeat, "Paint this many times (timings: the mean)")->check(CLI::Range(1, 100));
  cmd->add_flag("--whole-photo", args->whole_photo,
                "LaMa: paint with the whole photo at its size as the input, as the reference's bin/predict.py does "
                "(default: a crop around the region, at most 512 pixels on a side)");
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  add_runtime_options(cmd, args->runtime);
  cmd->footer(
      "LaMa's weights are read as published, never executed: big-lama's models/best.ckpt (github.com/advimman/lama,\n"
      "Apache-2.0; its README links the download). The region is painted in a crop around it, at most 512 pixels\n"
      "on a side, and put back at the photo's size.\n"
      "Examples:\n"
      "  instainpaint inpaint --inpainter big-lama/models/best.ckpt --image IMG_2707.png --mask label.png --out painted.png\n"
      "  instainpaint inpaint --inpainter ns --image IMG_2707.png --mask label.png --out ns.png");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
