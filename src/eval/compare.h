#pragma once
// Every image metric for one pair of image files (the `metrics` command): PSNR, SSIM, their
// masked and bounding-box variants, LPIPS (VGG, and AlexNet when its backbone is supplied)
// and masked LPIPS. Metrics whose weights are not supplied are listed under "unavailable"
// with the reason.
#include <filesystem>
#include <optional>

#include <nlohmann/json.hpp>

namespace ii {

struct CompareOptions {
  std::optional<std::filesystem::path> mask;  // 1 = region for the masked metrics
  // Backbones (absent: $INSTAINPAINT_LPIPS_VGG / $INSTAINPAINT_LPIPS_ALEX) and the folder of
  // the heads (absent: found as default_lpips_heads_path() does).
  std::optional<std::filesystem::path> lpips_vgg, lpips_alex, lpips_heads_dir;
};

// {"size": [W, H], "psnr": .., "ssim": .., ["masked_psnr", "masked_ssim", "box_psnr",
// "box_ssim", "mask_pixels"], ["lpips", "masked_lpips", "lpips_alex"], "unavailable": {..}};
// +inf is written as "inf", undefined values as null. Errors name the file that does not fit.
nlohmann::json compare_image_files(const std::filesystem::path& a, const std::filesystem::path& b,
                                   const CompareOptions& options = {});

}  // namespace ii
