// `instainpaint metrics`: image metrics of one pair of images.
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "eval/compare.h"

namespace ii::cli {

namespace {

struct MetricsArgs {
  std::string a, b, mask, lpips_vgg, lpips_alex, lpips_heads;
  bool json = false;
};

std::string shown(const nlohmann::json& v) {
  if (v.is_number()) return fmt::format("{:.6f}", v.get<double>());
  if (v.is_string()) return v.get<std::string>();
  return "undefined";
}

void run(const MetricsArgs& args) {
  CompareOptions o;
  o.mask = optional_path(args.mask);
  o.lpips_vgg = optional_path(args.lpips_vgg);
  o.lpips_alex = optional_path(args.lpips_alex);
  o.lpips_heads_dir = optional_path(args.lpips_heads);
  const nlohmann::json m = compare_image_files(args.a, args.b, o);
  if (args.json) {
    fmt::print("{}\n", m.dump(2));
    return;
  }
  for (const char* key : {"psnr", "ssim", "masked_psnr", "masked_ssim", "box_psnr", "box_ssim", "lpips", "masked_lpips",
                          "lpips_alex", "mask_pixels"})
    if (m.contains(key))
      fmt::print("{:<13} {}\n", key, key == std::string("mask_pixels") ? m[key].dump() : shown(m[key]));
  for (const auto& [key, reason] : m["unavailable"].items())
    fmt::print("{:<13} unavailable: {}\n", key, reason.get<std::string>());
}

}  // namespace

void add_metrics_command(CLI::App& app) {
  auto args = std::make_shared<MetricsArgs>();
  auto* cmd = app.add_subcommand("metrics", "Compare two images: PSNR, SSIM, LPIPS, masked and bounding-box variants");
  cmd->add_option("A", args->a, "First image (e.g. the prediction)")->required()->check(CLI::ExistingFile);
  cmd->add_option("B", args->b, "Second image (e.g. the ground truth), same size")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--mask", args->mask, "Mask image (white/1 = region) for masked and bounding-box metrics")
      ->check(CLI::ExistingFile);
  cmd->add_option("--lpips-vgg", args->lpips_vgg,
                  "torchvision VGG16 ImageNet weights (vgg16-397923af.pth) for LPIPS; default $INSTAINPAINT_LPIPS_VGG");
  cmd->add_option("--lpips-alex", args->lpips_alex,
                  "torchvision AlexNet weights (alexnet-owt-7be5be79.pth) for LPIPS-Alex; default "
                  "$INSTAINPAINT_LPIPS_ALEX");
  cmd->add_option("--lpips-heads", args->lpips_heads,
                  "Folder of the LPIPS heads vgg.safetensors / alex.safetensors (default: $INSTAINPAINT_LPIPS_HEADS, "
                  "else shared/data/lpips found above the working or executable folder)")
      ->check(CLI::ExistingDirectory);
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  cmd->footer(
      "Images are compared in [0,1] (alpha composited on white). PSNR is \"inf\" for identical images.\n"
      "SSIM: Gaussian window 11, sigma 1.5; masked SSIM averages the SSIM map over the mask; box_*: on\n"
      "the mask's bounding box. LPIPS v0.1 (VGG): the backbone is not redistributed, supply it.\n"
      "Example: instainpaint metrics render.png truth.png --mask mask.png --lpips-vgg vgg16-397923af.pth");
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
