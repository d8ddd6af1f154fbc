#include "io/image.h"

#include <stb_image.h>
#include <stb_image_write.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>
#include <cmath>
#include <memory>
#include <string>

#include "common/error.h"
#include "common/files.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

// Every image is probed against this before it is decoded (a small file can claim a huge
// image: 16000 x 16000 black pixels are a 750 KB PNG and 3 GB decoded): 134 M pixels, more
// than any camera's (16384 x 8192).
constexpr long kMaxPixels = 1L << 27;

std::vector<uint8_t> read_encoded(const fs::path& path) {
  auto bytes = read_file_bytes(path);
  if (bytes.empty()) fail_file(path, "empty file, expected an image");
  if (bytes.size() > static_cast<size_t>(INT32_MAX)) fail_file(path, "image file too large");
  return bytes;
}

ImageInfo info_from_memory(const std::vector<uint8_t>& bytes, const fs::path& path) {
  ImageInfo info;
  const int n = static_cast<int>(bytes.size());
  if (!stbi_info_from_memory(bytes.data(), n, &info.width, &info.height, &info.channels))
    fail_file(path, "not a readable image ({})", stbi_failure_reason());
  if (info.width <= 0 || info.height <= 0)
    fail_file(path, "implausible image size {}x{}", info.width, info.height);
  if (static_cast<long>(info.width) * info.height > kMaxPixels)
    fail_file(path, "{}x{} pixels, more than instainpaint decodes (at most {} million)", info.width, info.height,
              kMaxPixels / 1000000);
  info.bit_depth = stbi_is_16_bit_from_memory(bytes.data(), n) ? 16 : 8;
  return info;
}

}  // namespace

ImageInfo probe_image(const fs::path& path) {
  // stb needs only the first bytes of a header, but PNG/JPEG headers can sit after metadata
  // blocks; reading the whole file is simplest and images here are small.
  return info_from_memory(read_encoded(path), path);
}

DecodedImage decode_image(const fs::path& path) {
  const auto bytes = read_encoded(path);
  const ImageInfo info = info_from_memory(bytes, path);
  const int n = static_cast<int>(bytes.size());
  int w = 0, h = 0, c = 0;
  std::vector<float> values;
  if (info.bit_depth == 16) {
    std::unique_ptr<stbi_us, void (*)(void*)> data(
        stbi_load_16_from_memory(bytes.data(), n, &w, &h, &c, 0), stbi_image_free);
    if (!data) fail_file(path, "cannot decode image ({})", stbi_failure_reason());
    values.resize(static_cast<size_t>(w) * h * c);
    for (size_t i = 0; i < values.size(); ++i) values[i] = data.get()[i] / 65535.0f;
  } else {
    std::unique_ptr<stbi_uc, void (*)(void*)> data(
        stbi_load_from_memory(bytes.data(), n, &w, &h, &c, 0), stbi_image_free);
    if (!data) fail_file(path, "cannot decode image ({})", stbi_failure_reason());
    values.resize(static_cast<size_t>(w) * h * c);
    for (size_t i = 0; i < values.size(); ++i) values[i] = data.get()[i] / 255.0f;
  }

  DecodedImage out;
  out.bit_depth = info.bit_depth;
  out.color = Image(w, h, 3);
  const bool has_alpha = (c == 2 || c == 4);
  if (has_alpha) out.alpha = Image(w, h, 1);
  const int colour_channels = (c >= 3) ? 3 : 1;
  for (size_t p = 0; p < static_cast<size_t>(w) * h; ++p) {
    for (int k = 0; k < 3; ++k)
      out.color.pixels[p * 3 + k] = values[p * c + (colour_channels == 3 ? k : 0)];
    if (has_alpha) out.alpha->pixels[p] = values[p * c + c - 1];
  }
  return out;
}

Image read_image_rgb(const fs::path& path) {
  DecodedImage d = decode_image(path);
  if (d.alpha) {
    for (size_t p = 0; p < d.alpha->pixels.size(); ++p) {
      const float a = d.alpha->pixels[p];
      for (int k = 0; k < 3; ++k) {
        float& v = d.color.pixels[p * 3 + k];
        // Official convention: rgb + (1 - alpha), i.e. premultiplied colour over white.
        v = std::min(1.0f, v * a + (1.0f - a));
      }
    }
  }
  return std::move(d.color);
}

Image read_mask(const fs::path& path) {
  const DecodedImage d = decode_image(path);
  Image mask(d.color.width, d.color.height, 1);
  float max_value = 0.f;
  for (size_t p = 0; p < mask.pixels.size(); ++p) max_value = std::max(max_value, d.color.pixels[p * 3]);
  // {0,1}-valued 8-bit files decode to {0, 1/255}; treat any non-zero value as object then.
  const float one_step = d.bit_depth == 16 ? 1.0f / 65535.0f : 1.0f / 255.0f;
  const bool zero_one_encoding = max_value <= one_step * 1.5f;
  const float threshold = zero_one_encoding ? one_step * 0.5f : 0.5f;
  for (size_t p = 0; p < mask.pixels.size(); ++p)
    mask.pixels[p] = d.color.pixels[p * 3] >= threshold ? 1.f : 0.f;
  return mask;
}

namespace {

void check_writable(const fs::path& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0) fail_file(path, "cannot write an empty image");
  if (image.channels < 1 || image.channels > 4)
    fail_file(path, "cannot write an image with {} channels", image.channels);
  if (image.pixels.size() != static_cast<size_t>(image.width) * image.height * image.channels)
    fail_file(path, "image buffer size does not match {}x{}x{}", image.width, image.height,
              image.channels);
}

void append_bytes(void* context, void* data, int size) {
  auto* out = static_cast<std::string*>(context);
  out->append(static_cast<const char*>(data), static_cast<size_t>(size));
}

uint8_t to_u8(float v) {
  if (!(v == v)) v = 0.f;  // NaN -> black
  return static_cast<uint8_t>(std::lround(std::clamp(v, 0.f, 1.f) * 255.f));
}

uint32_t crc32_png(const uint8_t* data, size_t n, uint32_t crc = 0xffffffffu) {
  static const auto table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  for (size_t i = 0; i < n; ++i) crc = table[(crc ^ data[i]) & 0xff] ^ (crc >> 8);
  return crc;
}

void put_u32_be(std::string& out, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<char>((v >> s) & 0xff));
}

void put_chunk(std::string& out, const char* type, const std::string& payload) {
  put_u32_be(out, static_cast<uint32_t>(payload.size()));
  std::string body = std::string(type, 4) + payload;
  out += body;
  put_u32_be(out, crc32_png(reinterpret_cast<const uint8_t*>(body.data()), body.size()) ^ 0xffffffffu);
}

// One filtered PNG row: `type` (0 none, 1 sub, 2 up, 4 Paeth) of `row` against the row above
// (`above`, zeros for the first), `bpp` bytes a pixel.
void filter_row(int type, const uint8_t* row, const uint8_t* above, size_t n, size_t bpp, uint8_t* out) {
  for (size_t i = 0; i < n; ++i) {
    const int a = i >= bpp ? row[i - bpp] : 0, b = above[i], c = i >= bpp ? above[i - bpp] : 0;
    int predicted = 0;
    if (type == 1) {
      predicted = a;
    } else if (type == 2) {
      predicted = b;
    } else if (type == 4) {
      const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
      predicted = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
    }
    out[i] = static_cast<uint8_t>(row[i] - predicted);
  }
}

// PNG of 8- or 16-bit samples (big-endian, as PNG stores them), assembled here: each row gets
// the filter whose bytes sum smallest as signed values (libpng's heuristic), then zlib at its
// fastest level. stb's own encoder took 50-100 ms for a 904 x 512 render (eval writes 40 of
// them beside its renders); this takes a fraction of that for files of about the same size.
std::string encode_png(const std::vector<uint8_t>& samples, int width, int height, int channels, int bit_depth) {
  static const int colour_type[] = {0, 0, 4, 2, 6};  // grey, grey+alpha, RGB, RGBA
  const size_t bpp = static_cast<size_t>(channels) * (bit_depth / 8);
  const size_t row_bytes = static_cast<size_t>(width) * bpp;
  std::vector<uint8_t> filtered((row_bytes + 1) * height), zeros(row_bytes, 0), candidate(row_bytes);
  for (int y = 0; y < height; ++y) {
    const uint8_t* row = &samples[y * row_bytes];
    const uint8_t* above = y > 0 ? &samples[(y - 1) * row_bytes] : zeros.data();
    uint8_t* out = &filtered[y * (row_bytes + 1)];
    size_t best_cost = SIZE_MAX;
    for (const int type : {0, 1, 2, 4}) {
      filter_row(type, row, above, row_bytes, bpp, candidate.data());
      size_t cost = 0;
      for (const uint8_t v : candidate) cost += static_cast<size_t>(std::abs(static_cast<int8_t>(v)));
      if (cost < best_cost) {
        best_cost = cost;
        out[0] = static_cast<uint8_t>(type);
        std::copy(candidate.begin(), candidate.end(), out + 1);
      }
    }
  }
  uLongf zlen = compressBound(filtered.size());
  std::string z(zlen, '\0');
  if (compress2(reinterpret_cast<Bytef*>(z.data()), &zlen, filtered.data(), filtered.size(), Z_BEST_SPEED) != Z_OK)
    fail("PNG compression failed");
  z.resize(zlen);
  std::string out("\x89PNG\r\n\x1a\n", 8);
  std::string ihdr;
  put_u32_be(ihdr, width);
  put_u32_be(ihdr, height);
  ihdr += static_cast<char>(bit_depth);
  ihdr += static_cast<char>(colour_type[channels]);
  ihdr += std::string(3, '\0');  // deflate, adaptive filtering, no interlace
  put_chunk(out, "IHDR", ihdr);
  put_chunk(out, "IDAT", z);
  put_chunk(out, "IEND", "");
  return out;
}

}  // namespace

void write_png(const fs::path& path, const Image& image, int bit_depth) {
  check_writable(path, image);
  if (bit_depth != 8 && bit_depth != 16) fail_file(path, "PNG bit depth must be 8 or 16, got {}", bit_depth);
  std::vector<uint8_t> samples(image.pixels.size() * (bit_depth / 8));
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    if (bit_depth == 8) {
      samples[i] = to_u8(image.pixels[i]);
      continue;
    }
    float v = image.pixels[i];
    if (!(v == v)) v = 0.f;
    const auto s = static_cast<uint16_t>(std::lround(std::clamp(v, 0.f, 1.f) * 65535.f));
    samples[2 * i] = static_cast<uint8_t>(s >> 8);
    samples[2 * i + 1] = static_cast<uint8_t>(s & 0xff);
  }
  write_file_atomic(path, encode_png(samples, image.width, image.height, image.channels, bit_depth));
}

void write_jpeg(const fs::path& path, const Image& image, int quality) {
  check_writable(path, image);
  if (image.channels == 2 || image.channels == 4) fail_file(path, "JPEG has no alpha channel");
  std::vector<uint8_t> bytes(image.pixels.size());
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = to_u8(image.pixels[i]);
  std::string encoded;
  if (!stbi_write_jpg_to_func(append_bytes, &encoded, image.width, image.height, image.channels,
                              bytes.data(), std::clamp(quality, 1, 100)))
    fail_file(path, "JPEG encoding failed");
  write_file_atomic(path, encoded);
}

}  // namespace ii
