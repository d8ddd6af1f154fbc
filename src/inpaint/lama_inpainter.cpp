#include "inpaint/lama_inpainter.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <opencv2/imgproc.hpp>

#include "common/cpu_features.h"
#include "common/error.h"
#include "data/opencv_image.h"
#include "io/file_hash.h"

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

cv::Mat as_float_mat(const Image& image) {
  return cv::Mat(image.height, image.width, CV_32FC(image.channels), const_cast<float*>(image.pixels.data())).clone();
}

Image as_image(const cv::Mat& mat) {
  Image out(mat.cols, mat.rows, mat.channels());
  const cv::Mat c = mat.isContinuous() ? mat : mat.clone();
  std::copy(c.ptr<float>(), c.ptr<float>() + out.pixels.size(), out.pixels.begin());
  return out;
}

}  // namespace

LamaInpainter::LamaInpainter(Lama lama, LamaOptions options)
    : lama_(std::move(lama)), options_(options), sha256_(sha256_of_file(lama_.file())) {}

nlohmann::json LamaInpainter::describe() const {
  return {{"name", name()}, {"network", lama_.description()}, {"precision", lama_.bf16() ? "bf16" : "fp32"},
          {"file", lama_.file().string()}, {"sha256", sha256_}};
}

Image LamaInpainter::paint(const Image& rgb, const Image& mask) const {
  const cv::Rect box = region_box(mask);
  if (box.empty()) return rgb;
  if (options_.whole_photo) return lama_.inpaint(rgb, mask);
  const int margin = std::max(options_.min_margin, static_cast<int>(std::lround(options_.margin * std::max(box.width, box.height))));
  const cv::Rect crop = cv::Rect(box.x - margin, box.y - margin, box.width + 2 * margin, box.height + 2 * margin) &
                        cv::Rect(0, 0, rgb.width, rgb.height);
  cv::Mat photo = as_float_mat(rgb)(crop).clone(), region = as_float_mat(mask)(crop).clone();
  const double scale = std::min(1.0, static_cast<double>(options_.work_side) / std::max(crop.width, crop.height));
  if (scale < 1) {
    const cv::Size size(std::max(8, static_cast<int>(std::lround(crop.width * scale))),
                        std::max(8, static_cast<int>(std::lround(crop.height * scale))));
    cv::resize(photo, photo, size, 0, 0, cv::INTER_AREA);
    cv::resize(region, region, size, 0, 0, cv::INTER_AREA);
    region = region > 0.f;  // any of the region in a small pixel: painted
    region.convertTo(region, CV_32F, 1.0 / 255);
  }
  cv::Mat painted = as_float_mat(lama_.inpaint(as_image(photo), as_image(region)));
  if (scale < 1) cv::resize(painted, painted, crop.size(), 0, 0, cv::INTER_CUBIC);
  // Back into the photo inside the region only: the rest keeps its own pixels.
  Image out = rgb;
  for (int y = 0; y < crop.height; ++y)
    for (int x = 0; x < crop.width; ++x) {
      if (mask.at(crop.y + y, crop.x + x) <= 0.5f) continue;
      const cv::Vec3f& p = painted.at<cv::Vec3f>(y, x);
      for (int c = 0; c < 3; ++c) out.at(crop.y + y, crop.x + x, c) = std::clamp(p[c], 0.f, 1.f);
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
  if (!flag.empty()) return inpainter_from_name(flag, options);
  if (const char* env = std::getenv("INSTAINPAINT_INPAINTER"); env && *env) return inpainter_from_name(env, options);
  return inpainter_from_name(fallback, options);
}

}  // namespace ii
