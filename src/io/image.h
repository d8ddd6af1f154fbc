#pragma once
// Images as plain float arrays (row-major, channels interleaved, values in [0,1]).
// Decoding and encoding go through stb; 8- and 16-bit PNG, JPEG, BMP, TGA are read.
#include <filesystem>
#include <optional>
#include <vector>

namespace ii {

struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<float> pixels;  // size height*width*channels, HWC

  Image() = default;
  Image(int w, int h, int c, float fill = 0.f)
      : width(w), height(h), channels(c), pixels(static_cast<size_t>(w) * h * c, fill) {}

  bool empty() const { return pixels.empty(); }
  float& at(int y, int x, int c = 0) { return pixels[(static_cast<size_t>(y) * width + x) * channels + c]; }
  float at(int y, int x, int c = 0) const { return pixels[(static_cast<size_t>(y) * width + x) * channels + c]; }
};

struct ImageInfo {
  int width = 0;
  int height = 0;
  int channels = 0;  // as stored: 1 grey, 2 grey+alpha, 3 RGB, 4 RGBA
  int bit_depth = 8;
};

// Reads only the header.
ImageInfo probe_image(const std::filesystem::path& path);

// Full decode keeping what the file holds: `color` has 3 channels (grey is expanded),
// `alpha` is set when the file has an alpha channel.
struct DecodedImage {
  Image color;
  std::optional<Image> alpha;  // 1 channel, [0,1]
  int bit_depth = 8;
};
DecodedImage decode_image(const std::filesystem::path& path);

// RGB image; an alpha channel is composited on white (rgb + (1 - alpha)), as the official
// evaluation does.
Image read_image_rgb(const std::filesystem::path& path);

// Binary object mask (1 channel, values exactly 0 or 1). Accepts {0,1} and {0,255} (or
// {0,65535}) encodings; any non-zero value of a {0,1} file and any value at or above half
// range otherwise counts as object. Colour masks use their first channel.
Image read_mask(const std::filesystem::path& path);

// Writes 8- or 16-bit PNG (1, 3 or 4 channels; values clamped to [0,1]), atomically.
void write_png(const std::filesystem::path& path, const Image& image, int bit_depth = 8);
// Baseline JPEG, atomically.
void write_jpeg(const std::filesystem::path& path, const Image& image, int quality = 95);

}  // namespace ii
