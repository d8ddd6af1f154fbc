#pragma once
// Pillow's bilinear resize of 8-bit images (Image.resize with Image.BILINEAR, as torchvision's
// resize of a PIL image calls it), to the byte: SAM's predictor resizes each photo this way, so
// the segmenter sees the same pixels as the reference code. A triangle filter widened by the
// scale when shrinking, coefficients in 22-bit fixed point, rows first, then columns, each pass
// rounded to bytes. Torch-free.
#include <cstdint>
#include <vector>

namespace ii {

struct Bytes8Image {
  int width = 0, height = 0, channels = 0;
  std::vector<uint8_t> pixels;  // HWC
};

Bytes8Image resize_like_pillow(const Bytes8Image& image, int width, int height);

}  // namespace ii
