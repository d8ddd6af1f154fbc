#include "data/inpaint2d.h"

#include <opencv2/photo.hpp>

#include "common/error.h"

namespace ii {

std::string inpainter_name(ClassicalInpainter method) {
  switch (method) {
    case ClassicalInpainter::NavierStokes: return "ns";
    case ClassicalInpainter::Patches: return "patch";
    default: return "telea";
  }
}

ClassicalInpainter parse_inpainter(const std::string& name) {
  if (name == "telea") return ClassicalInpainter::Telea;
  if (name == "ns") return ClassicalInpainter::NavierStokes;
  if (name == "patch") return ClassicalInpainter::Patches;
  fail("unknown 2D inpainter '{}' (telea, ns or patch)", name);
}

Image inpaint_classical(const Image& rgb, const Image& mask, ClassicalInpainter method, double radius) {
  if (rgb.channels != 3 || mask.channels != 1 || rgb.width != mask.width || rgb.height != mask.height)
    fail("inpainting needs an RGB image and a one-channel mask of the same size");
  if (method == ClassicalInpainter::Patches) return inpaint_patches(rgb, mask);
  // cv::inpaint works on 8-bit images.
  cv::Mat src(rgb.height, rgb.width, CV_8UC3), m(rgb.height, rgb.width, CV_8UC1);
  for (size_t i = 0; i < rgb.pixels.size(); ++i)
    src.data[i] = static_cast<uint8_t>(std::clamp(rgb.pixels[i], 0.f, 1.f) * 255.f + 0.5f);
  for (size_t i = 0; i < mask.pixels.size(); ++i) m.data[i] = mask.pixels[i] > 0.5f ? 255 : 0;
  cv::Mat dst;
  cv::inpaint(src, m, dst, radius, method == ClassicalInpainter::NavierStokes ? cv::INPAINT_NS : cv::INPAINT_TELEA);
  Image out(rgb.width, rgb.height, 3);
  for (size_t i = 0; i < out.pixels.size(); ++i) out.pixels[i] = dst.data[i] / 255.f;
  return out;
}

nlohmann::json Inpainter::describe() const {
  return learned ? learned->describe() : nlohmann::json{{"name", inpainter_name(classical)}};
}

Image Inpainter::paint(const Image& rgb, const Image& mask) const {
  if (!learned) return inpaint_classical(rgb, mask, classical);
  if (rgb.channels != 3 || mask.channels != 1 || rgb.width != mask.width || rgb.height != mask.height)
    fail("inpainting needs an RGB image and a one-channel mask of the same size");
  return learned->paint(rgb, mask);
}

}  // namespace ii
