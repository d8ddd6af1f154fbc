#include "eval/compare.h"

#include <cmath>

#include "common/error.h"
#include "eval/lpips.h"
#include "eval/metrics.h"
#include "eval/report.h"
#include "io/image.h"
#include "tensor/image_tensor.h"

namespace ii {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

std::optional<fs::path> heads_in(const std::optional<fs::path>& dir, LpipsNet net) {
  if (!dir) return std::nullopt;
  return *dir / (std::string(lpips_net_name(net)) + ".safetensors");
}

}  // namespace

json compare_image_files(const fs::path& a_file, const fs::path& b_file, const CompareOptions& o) {
  const Image a = read_image_rgb(a_file), b = read_image_rgb(b_file);
  if (a.width != b.width || a.height != b.height)
    fail_file(b_file, "{}x{}, but {} is {}x{}: the images must have the same size", b.width, b.height, a_file.string(),
              a.width, a.height);
  std::optional<Image> mask;
  if (o.mask) {
    mask = read_mask(*o.mask);
    if (mask->width != a.width || mask->height != a.height)
      fail_file(*o.mask, "mask of {}x{}, but the images are {}x{}", mask->width, mask->height, a.width, a.height);
  }

  json out = {{"size", {a.width, a.height}}};
  json unavailable = json::object();
  torch::NoGradGuard no_grad;
  const torch::Tensor x = image_to_tensor(a), y = image_to_tensor(b);
  out["psnr"] = metric_json(psnr(x, y)[0].item<double>());
  if (std::min(a.width, a.height) >= 11)
    out["ssim"] = metric_json(ssim(x, y)[0].item<double>());
  else
    unavailable["ssim"] = "the images are smaller than the 11x11 SSIM window";
  torch::Tensor m;
  if (mask) {
    m = image_to_tensor(*mask);
    out["mask_pixels"] = (m > 0.5).sum().item<int64_t>();
    out["masked_psnr"] = metric_json(masked_psnr(x, y, m)[0].item<double>());
    out["box_psnr"] = metric_json(box_psnr(x, y, m));
    if (out.contains("ssim")) {
      out["masked_ssim"] = metric_json(masked_ssim(x, y, m)[0].item<double>());
      out["box_ssim"] = metric_json(box_ssim(x, y, m));
    }
  }

  const torch::Tensor xs = x * 2 - 1, ys = y * 2 - 1;
  if (lpips_backbone_path(LpipsNet::vgg, o.lpips_vgg)) {
    const Lpips vgg = Lpips::load(LpipsNet::vgg, o.lpips_vgg, heads_in(o.lpips_heads_dir, LpipsNet::vgg));
    out["lpips"] = metric_json(vgg.forward(xs, ys)[0].item<double>());
    if (mask) out["masked_lpips"] = metric_json(vgg.masked(xs, ys, m)[0].item<double>());
  } else {
    unavailable["lpips"] = lpips_missing_backbone_message(LpipsNet::vgg);
  }
  if (lpips_backbone_path(LpipsNet::alex, o.lpips_alex)) {
    const Lpips alex = Lpips::load(LpipsNet::alex, o.lpips_alex, heads_in(o.lpips_heads_dir, LpipsNet::alex));
    out["lpips_alex"] = metric_json(alex.forward(xs, ys)[0].item<double>());
  }
  out["unavailable"] = unavailable;
  return out;
}

}  // namespace ii
