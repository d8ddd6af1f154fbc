// `instainpaint segment`: one photo segmented by SAM or MobileSAM from clicks or a box.
#include <array>
#include <sstream>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "camera/click.h"
#include "cli/commands.h"
#include "cli/edit_options.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "common/files.h"
#include "common/stage_times.h"
#include "segment/segmenter.h"

namespace ii::cli {

namespace {

struct SegmentArgs {
  std::string segmenter, image, out = "mask.png", box, overlay;
  std::vector<std::string> clicks, not_clicks;
  bool all_masks = false, json = false;
  int repeat = 1;
  RuntimeOptions runtime;
};

// The photo darkened outside the mask, the mask's pixels tinted.
Image overlay_of(const Image& photo, const Image& mask) {
  Image out = photo;
  for (int y = 0; y < photo.height; ++y)
    for (int x = 0; x < photo.width; ++x) {
      const bool in = mask.at(y, x) > 0.5f;
      for (int c = 0; c < 3; ++c) {
        float& v = out.at(y, x, c);
        v = in ? 0.6f * v + 0.4f * (c == 0 ? 1.f : c == 1 ? 0.35f : 0.2f) : 0.45f * v;
      }
    }
  return out;
}

void run(const SegmentArgs& args) {
  apply_runtime_options(args.runtime);
  const SegmenterPrecision precision = parse_segmenter_precision(args.runtime.precision);
  const auto path = segmenter_path(args.segmenter);
  if (!path)
    fail("--segmenter: no segmentation network in the cache; bring one with: instainpaint models get mobile-sam "
         "(or name a SAM or MobileSAM file)");
  StageTimes stages;
  const Segmenter segmenter = stages.time("read segmenter", [&] { return Segmenter::load(*path, precision); });
  const Image photo = stages.time("read photo", [&] { return read_image_rgb(args.image); });
  SegmentPrompt prompt;
  // A click's pixel centres are at +0.5; SAM's points are pixel indices (it adds the 0.5 itself).
  for (const std::string& c : args.clicks) {
    const Click k = parse_click(c, "--click");
    prompt.points.push_back({k.x - 0.5, k.y - 0.5, true});
  }
  for (const std::string& c : args.not_clicks) {
    const Click k = parse_click(c, "--not");
    prompt.points.push_back({k.x - 0.5, k.y - 0.5, false});
  }
  if (!args.box.empty()) prompt.box = parse_view_box(args.box, "--box");
  if (prompt.points.empty() && !prompt.box) fail("give at least one --click or a --box");
  prompt.multimask = prompt.points.size() == 1 && !prompt.box;  // SAM's advice: one point is ambiguous
  SegmenterImage encoded;
  Segmentation s;
  for (int i = 0; i < args.repeat; ++i) {
    encoded = stages.time("encode photo", [&] { return segmenter.encode(photo); });
    s = stages.time("decode prompt", [&] { return segmenter.segment(encoded, prompt); });
  }
  const int best = s.best();
  const Image mask = s.mask(best);
  stages.time("write", [&] {
    write_png(args.out, mask);
    if (!args.overlay.empty()) write_jpeg(args.overlay, overlay_of(photo, mask), 90);
    if (args.all_masks)
      for (int k = 0; k < static_cast<int>(s.scores.size(0)); ++k)
        write_png(fmt::format("{}-{}.png", args.out.substr(0, args.out.rfind('.')), k), s.mask(k));
  });
  int64_t pixels = 0;
  for (float v : mask.pixels) pixels += v > 0.5f;
  nlohmann::json scores = nlohmann::json::array();
  for (int k = 0; k < static_cast<int>(s.scores.size(0)); ++k) scores.push_back(s.scores[k].item<double>());
  nlohmann::json summary = segmenter.file_description();  // file, sha256, "from": the cache or a path
  summary.update({{"segmenter", segmenter.description()}, {"precision", segmenter.bf16() ? "bf16" : "fp32"},
                  {"mask", args.out}, {"chosen", best}, {"scores", scores},
                  {"pixels", pixels}, {"stages", stages.to_json()}});
  if (args.json) {
    fmt::print("{}\n", summary.dump(2));
    return;
  }
  fmt::print("{}: {} ({})\n", path->string(), segmenter.description(), segmenter.bf16() ? "bf16" : "fp32");
  fmt::print("mask {} of {} (score {:.3f}): {} pixels of {} -> {}\n", best + 1, scores.size(), scores[best].get<double>(),
             pixels, mask.pixels.size(), args.out);
  for (const StageTimes::Stage& st : stages.stages())
    fmt::print("  {:<16} {:8.1f} ms{}\n", st.name, st.ms / std::max(1, st.calls), st.calls > 1 ? fmt::format(" (mean of {})", st.calls) : "");
}

}  // namespace

void add_segment_command(CLI::App& app) {
  auto args = std::make_shared<SegmentArgs>();
  auto* cmd = app.add_subcommand("segment", "Segment one photo with SAM or MobileSAM from clicks or a box");
  cmd->add_option("--segmenter", args->segmenter,
                  kSegmenterHelp);
  cmd->add_option("--image", args->image, "The photo")->required()->check(CLI::ExistingFile);
  cmd->add_option("--click", args->clicks, "X,Y on the object (pixels, x right, y down); repeat to add");
  cmd->add_option("--not", args->not_clicks, "X,Y on something that is not the object; repeatable");
  cmd->add_option("--box", args->box, "X0,Y0,X1,Y1 around the object");
  cmd->add_option("--out", args->out, "The mask (PNG, white = object)")->capture_default_str();
  cmd->add_option("--overlay", args->overlay, "Also the photo with the mask tinted (JPEG)");
  cmd->add_flag("--all-masks", args->all_masks, "Also each of SAM's three masks as OUT-0.png, OUT-1.png, OUT-2.png");
  cmd->add_option("--repeat", args->repeat, "Encode and decode this many times (timings: the mean)")
      ->check(CLI::Range(1, 100));
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  add_runtime_options(cmd, args->runtime);
  cmd->footer(
      "The weights are read as published, never executed: MobileSAM's mobile_sam.pt (40 MB, github.com/\n"
      "ChaoningZhang/MobileSAM, weights/) or SAM's sam_vit_b_01ec64.pth / sam_vit_l_0b3195.pth /\n"
      "sam_vit_h_4b8939.pth (github.com/facebookresearch/segment-anything). One click gives SAM's three\n"
      "masks and the one it scores best is kept; more clicks, --not or --box give one mask.\n"
      "Examples:\n"
      "  instainpaint segment --segmenter mobile_sam.pt --image IMG_2707.JPG --click 681,216 --overlay look.jpg\n"
      "  instainpaint segment --segmenter mobile_sam.pt --image IMG_2707.JPG --box 520,120,840,330 --out box.png");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
