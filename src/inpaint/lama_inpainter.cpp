#include "inpaint/lama_inpainter.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <opencv2/imgproc.hpp>

#include "common/cpu_features.h"
#include "common/error.h"
#include "data/image_ops.h"
#include "models/cache.h"

namespace ii {

namespace {

// The region's box (pixels > 0.5); empty when there is none.
cv::Rect region_box(const Image& mask) {
  int x0 = mask.width, y0 = mask.height, x1 = -1, y1 = -1;
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x)
      if (mask.at(y, x) > 0.5f) x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
  return x1 < 0 ? cv::Rect() : cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1);
}

}  // namespace

LamaInpainter::LamaInpainter(Lama lama, LamaOptions options)
    : lama_(std::move(lama)), options_(options), file_(model_file_description(lama_.file())) {}

nlohmann::json LamaInpainter::describe() const {
  nlohmann::json d = {{"name", name()}, {"network", lama_.description()}, {"precision", lama_.bf16() ? "bf16" : "fp32"}};
  d.update(file_);  // file, sha256, and "from": "the cache" or "a path"
  return d;
}

Image LamaInpainter::paint(const Image& rgb, const Image& mask) const {
  const cv::Rect box = region_box(mask);
  if (box.empty()) return rgb;
  if (options_.whole_photo) return lama_.inpaint(rgb, mask);
  const int margin =
      std::max(options_.min_margin, static_cast<int>(std::lround(options_.margin * std::max(box.width, box.height))));
  const cv::Rect at = cv::Rect(box.x - margin, box.y - margin, box.width + 2 * margin, box.height + 2 * margin) &
                      cv::Rect(0, 0, rgb.width, rgb.height);
  Image photo = crop(rgb, at.x, at.y, at.width, at.height), region = crop(mask, at.x, at.y, at.width, at.height);
  const double scale = std::min(1.0, static_cast<double>(options_.work_side) / std::max(at.width, at.height));
  if (scale < 1) {
    const int w = std::max(8, static_cast<int>(std::lround(at.width * scale)));
    const int h = std::max(8, static_cast<int>(std::lround(at.height * scale)));
    photo = resize_area(photo, w, h);
    region = resize_area(region, w, h);
    for (float& v : region.pixels) v = v > 0.f ? 1.f : 0.f;  // any of the region in a small pixel: painted
  }
  Image painted = lama_.inpaint(photo, region);
  if (scale < 1) painted = resize_cubic(painted, at.width, at.height);
  // Back into the photo inside the region only: the rest keeps its own pixels.
  Image out = rgb;
  for (int y = 0; y < at.height; ++y)
    for (int x = 0; x < at.width; ++x) {
      if (mask.at(at.y + y, at.x + x) <= 0.5f) continue;
      for (int c = 0; c < 3; ++c) out.at(at.y + y, at.x + x, c) = std::clamp(painted.at(y, x, c), 0.f, 1.f);
    }
  return out;
}

Inpainter inpainter_from_name(const std::string& name, const LamaOptions& options) {
  if (name == "telea" || name == "ns" || name == "patch") return parse_inpainter(name);
  std::error_code ec;
  if (!std::filesystem::exists(name, ec))
    fail("inpainter '{}': neither telea, ns, patch nor a LaMa file (big-lama/models/best.ckpt)", name);
  if (options.precision != "auto" && options.precision != "fp32" && options.precision != "bf16")
    fail("LaMa's precision '{}': auto, fp32 or bf16", options.precision);
  // On a GPU when LibTorch sees one, as the commands' --device auto (bf16 there); else the CPU.
  const bool gpu = options.device == "auto" ? torch::cuda::is_available() : options.device != "cpu";
  const torch::Device device = gpu ? torch::Device(options.device == "auto" ? "cuda" : options.device) : torch::kCPU;
  const bool bf16 = options.precision == "bf16" || (options.precision == "auto" && (gpu || cpu_features().native_bf16()));
  return Inpainter(std::make_shared<const LamaInpainter>(Lama::load(name, bf16, device), options));
}

Inpainter inpainter_from_flag(const std::string& flag, const std::string& fallback, const LamaOptions& options) {
  std::string value = flag;
  if (const char* env = std::getenv("INSTAINPAINT_INPAINTER"); value.empty() && env) value = env;
  if (value.empty() || value == "auto") {
    const ModelChoice cached = choose_model(ModelRole::Inpainter, "auto");
    return inpainter_from_name(cached.file ? cached.file->string() : fallback, options);
  }
  if (in_catalogue(value)) return inpainter_from_name(choose_model(ModelRole::Inpainter, value).file->string(), options);
  return inpainter_from_name(value, options);
}

}  // namespace ii
