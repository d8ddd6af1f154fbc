#include "segment/pillow_resize.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"

namespace ii {
namespace {

constexpr int kPrecisionBits = 32 - 8 - 2;

// One output sample's window of input samples and their fixed-point weights.
struct ResampleTaps {
  int ksize = 0;
  std::vector<int> first, count;  // per output sample
  std::vector<int32_t> weights;   // per output sample, ksize each
};

double triangle(double x) {
  x = std::abs(x);
  return x < 1.0 ? 1.0 - x : 0.0;
}

// Pillow's precompute_coeffs and normalize_coeffs_8bpc for the bilinear filter (support 1).
ResampleTaps taps_for(int in_size, int out_size) {
  const double scale = static_cast<double>(in_size) / out_size;
  const double filterscale = std::max(scale, 1.0);
  const double support = 1.0 * filterscale;
  ResampleTaps t;
  t.ksize = static_cast<int>(std::ceil(support)) * 2 + 1;
  t.first.resize(out_size);
  t.count.resize(out_size);
  t.weights.assign(static_cast<size_t>(out_size) * t.ksize, 0);
  std::vector<double> k(t.ksize);
  const double inv_filterscale = 1.0 / filterscale;
  for (int xx = 0; xx < out_size; ++xx) {
    const double center = (xx + 0.5) * scale;
    int xmin = static_cast<int>(center - support + 0.5);
    xmin = std::max(xmin, 0);
    int xmax = std::min(static_cast<int>(center + support + 0.5), in_size) - xmin;
    double ww = 0.0;
    for (int x = 0; x < xmax; ++x) {
      k[x] = triangle((x + xmin - center + 0.5) * inv_filterscale);
      ww += k[x];
    }
    for (int x = 0; x < xmax; ++x) {
      const double w = ww != 0.0 ? k[x] / ww : k[x];
      t.weights[static_cast<size_t>(xx) * t.ksize + x] =
          static_cast<int32_t>(w < 0 ? -0.5 + w * (1 << kPrecisionBits) : 0.5 + w * (1 << kPrecisionBits));
    }
    t.first[xx] = xmin;
    t.count[xx] = xmax;
  }
  return t;
}

uint8_t clip8(int32_t v) {
  const int32_t shifted = v >> kPrecisionBits;  // arithmetic shift, as Pillow's lookup index
  return static_cast<uint8_t>(std::clamp(shifted, 0, 255));
}

}  // namespace

Bytes8Image resize_like_pillow(const Bytes8Image& image, int width, int height) {
  if (width <= 0 || height <= 0 || image.width <= 0 || image.height <= 0)
    fail("resize of a {}x{} image to {}x{}: sizes must be positive", image.width, image.height, width, height);
  if (width == image.width && height == image.height) return image;  // Pillow returns a copy
  const int c = image.channels;
  const ResampleTaps vertical = taps_for(image.height, height);
  // Rows first, over the rows the vertical pass reads (Pillow's ybox).
  const int row_first = vertical.first[0];
  const int row_last = vertical.first[height - 1] + vertical.count[height - 1];
  Bytes8Image rows;
  const bool need_horizontal = width != image.width;
  if (need_horizontal) {
    const ResampleTaps horizontal = taps_for(image.width, width);
    rows.width = width;
    rows.height = row_last - row_first;
    rows.channels = c;
    rows.pixels.resize(static_cast<size_t>(rows.width) * rows.height * c);
    for (int y = 0; y < rows.height; ++y) {
      const uint8_t* in = image.pixels.data() + static_cast<size_t>(y + row_first) * image.width * c;
      uint8_t* out = rows.pixels.data() + static_cast<size_t>(y) * width * c;
      for (int x = 0; x < width; ++x) {
        const int32_t* k = horizontal.weights.data() + static_cast<size_t>(x) * horizontal.ksize;
        for (int ch = 0; ch < c; ++ch) {
          int32_t sum = 1 << (kPrecisionBits - 1);
          for (int i = 0; i < horizontal.count[x]; ++i) sum += in[(horizontal.first[x] + i) * c + ch] * k[i];
          out[x * c + ch] = clip8(sum);
        }
      }
    }
  }
  const Bytes8Image& source = need_horizontal ? rows : image;
  const int source_first = need_horizontal ? row_first : 0;
  if (height == image.height) return source;
  Bytes8Image out{width, height, c, std::vector<uint8_t>(static_cast<size_t>(width) * height * c)};
  for (int y = 0; y < height; ++y) {
    const int32_t* k = vertical.weights.data() + static_cast<size_t>(y) * vertical.ksize;
    const int first = vertical.first[y] - source_first;
    for (int x = 0; x < width * c; ++x) {
      int32_t sum = 1 << (kPrecisionBits - 1);
      for (int i = 0; i < vertical.count[y]; ++i)
        sum += source.pixels[static_cast<size_t>(first + i) * width * c + x] * k[i];
      out.pixels[static_cast<size_t>(y) * width * c + x] = clip8(sum);
    }
  }
  return out;
}

}  // namespace ii
