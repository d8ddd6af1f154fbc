// Gaussian splat PLY: standard layout round trips, ASCII and mixed-type files, the
// SuperSplat compressed layout (synthetic files with exactly known values and the real
// guitar/biker captures), and every kind of bad input with its exact message.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>

#include "common/files.h"
#include "io/ply.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace ply_test {

namespace fs = std::filesystem;
using test::file_bytes;
using test::raw;
using test::write_bytes;

constexpr double kSh0 = 0.28209479177387814;

template <typename T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

SplatCloud sample_cloud(size_t n, int rest) {
  SplatCloud c;
  c.sh_rest_per_channel = rest;
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      c.means.push_back(0.1f * static_cast<float>(i) + static_cast<float>(a) - 7.3f);
      c.normals.push_back(a == 2 ? 1.f : 0.f);
      c.sh_dc.push_back(0.3f * static_cast<float>(a) - 0.2f);
      c.log_scales.push_back(-3.f + static_cast<float>(a) / 3.f);
    }
    for (int k = 0; k < 3 * rest; ++k) c.sh_rest.push_back(0.01f * static_cast<float>(k) - 0.05f * static_cast<float>(i));
    c.opacity_logit.push_back(0.5f * static_cast<float>(i) - 1.f);
    for (int a = 0; a < 4; ++a) c.rotations.push_back(a == 0 ? 0.9f : 0.1f * static_cast<float>(a) * static_cast<float>(i % 3));
  }
  return c;
}

void expect_same(const SplatCloud& a, const SplatCloud& b) {
  EXPECT_EQ(a.size(), b.size());
  EXPECT_EQ(a.means, b.means);
  EXPECT_EQ(a.normals, b.normals);
  EXPECT_EQ(a.sh_dc, b.sh_dc);
  EXPECT_EQ(a.sh_rest, b.sh_rest);
  EXPECT_EQ(a.sh_rest_per_channel, b.sh_rest_per_channel);
  EXPECT_EQ(a.opacity_logit, b.opacity_logit);
  EXPECT_EQ(a.log_scales, b.log_scales);
  EXPECT_EQ(a.rotations, b.rotations);
}

TEST(Ply, StandardRoundTripIsBitExact) {
  const fs::path dir = test::temp_dir("ply");
  for (int rest : {0, 3, 8, 15}) {
    SCOPED_TRACE(rest);
    const fs::path p = dir / fmt::format("c{}.ply", rest);
    SplatCloud c = sample_cloud(300, rest);
    c.means[5] = std::numeric_limits<float>::denorm_min();
    c.opacity_logit[7] = -std::numeric_limits<float>::infinity();
    write_splat_ply(p, c);
    const SplatCloud back = read_splat_ply(p);
    expect_same(back, c);
    // Writing what was read gives the same bytes.
    write_splat_ply(dir / "again.ply", back);
    EXPECT_EQ(file_bytes(dir / "again.ply"), file_bytes(p));
    EXPECT_EQ(fs::file_size(p), file_bytes(p).find("end_header\n") + 11 + 300 * (17 + 3 * rest) * 4);
  }
}

TEST(Ply, WritesTheReferenceHeader) {
  const fs::path p = test::temp_dir("ply") / "h.ply";
  SplatCloud c = sample_cloud(2, 3);
  c.normals.clear();  // written as zeros
  write_splat_ply(p, c);
  std::string expected = "ply\nformat binary_little_endian 1.0\nelement vertex 2\n";
  for (const char* name : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"})
    expected += std::string("property float ") + name + "\n";
  for (int j = 0; j < 9; ++j) expected += fmt::format("property float f_rest_{}\n", j);
  for (const char* name : {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    expected += std::string("property float ") + name + "\n";
  expected += "end_header\n";
  const std::string bytes = file_bytes(p);
  ASSERT_EQ(bytes.substr(0, expected.size()), expected);
  // First row, in file order.
  std::vector<float> row(26);
  std::memcpy(row.data(), bytes.data() + expected.size(), 26 * 4);
  EXPECT_EQ(row[0], c.means[0]);
  EXPECT_EQ(row[3], 0.f);
  EXPECT_EQ(row[6], c.sh_dc[0]);
  EXPECT_EQ(row[9], c.sh_rest[0]);
  EXPECT_EQ(row[17], c.sh_rest[8]);
  EXPECT_EQ(row[18], c.opacity_logit[0]);
  EXPECT_EQ(row[19], c.log_scales[0]);
  EXPECT_EQ(row[22], c.rotations[0]);
  EXPECT_EQ(row[25], c.rotations[3]);
  EXPECT_EQ(read_splat_ply(p).normals, std::vector<float>(6, 0.f));
}

TEST(Ply, EmptyCloudRoundTrips) {
  const fs::path p = test::temp_dir("ply") / "empty.ply";
  write_splat_ply(p, SplatCloud{});
  const SplatCloud c = read_splat_ply(p);
  EXPECT_EQ(c.size(), 0u);
  EXPECT_TRUE(c.means.empty());
}

const char* kRequiredAscii =
    "property float opacity\nproperty float rot_0\nproperty float rot_1\nproperty float rot_2\n"
    "property float rot_3\nproperty float scale_0\nproperty float scale_1\nproperty float scale_2\n";

TEST(Ply, AsciiWithPropertiesInAnyOrderAndExtras) {
  const fs::path p = test::temp_dir("ply") / "a.ply";
  // CRLF line ends, a comment, an unknown uchar property, a double, no normals, and a face
  // element with a list property after the vertices.
  std::string text = std::string("ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nelement vertex 2\r\n") + kRequiredAscii +
                     "property double x\nproperty float y\nproperty float z\nproperty uchar red\n"
                     "property float f_dc_2\nproperty float f_dc_1\nproperty float f_dc_0\n"
                     "element face 1\nproperty list uchar int vertex_indices\nend_header\r\n"
                     "0.5 1 0 0 0 -1 -2 -3 10 20 30 255 0.3 0.2 0.1\r\n"
                     "-0.5 0.5 0.5 0.5 0.5 -4 -5 -6 1e-3 +2 -3.5 0 1 2 3\n"
                     "3 0 1 2\n";
  write_bytes(p, text);
  const SplatCloud c = read_splat_ply(p);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.means, (std::vector<float>{10, 20, 30, 1e-3f, 2, -3.5f}));
  EXPECT_EQ(c.sh_dc, (std::vector<float>{0.1f, 0.2f, 0.3f, 3, 2, 1}));
  EXPECT_EQ(c.log_scales, (std::vector<float>{-1, -2, -3, -4, -5, -6}));
  EXPECT_EQ(c.opacity_logit, (std::vector<float>{0.5f, -0.5f}));
  EXPECT_EQ(c.rotations, (std::vector<float>{1, 0, 0, 0, 0.5f, 0.5f, 0.5f, 0.5f}));
  EXPECT_EQ(c.normals, std::vector<float>(6, 0.f));
  EXPECT_EQ(c.sh_rest_per_channel, 0);
  EXPECT_TRUE(c.sh_rest.empty());
}

TEST(Ply, BinaryWithMixedTypesAndOtherElements) {
  const fs::path p = test::temp_dir("ply") / "b.ply";
  // An element with a list property before the vertices must be skipped row by row.
  std::string h =
      "ply\nformat binary_little_endian 1.0\nelement camera 2\nproperty list uchar float params\n"
      "property short id\nelement vertex 2\nproperty double x\nproperty int y\nproperty ushort z\n"
      "property uchar flags\nproperty float nz\n";
  for (int j = 8; j >= 0; --j) h += fmt::format("property float f_rest_{}\n", j);  // reversed order
  h += std::string(kRequiredAscii) + "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\nend_header\n";
  std::string body;
  put<uint8_t>(body, 2);  // camera 0: 2 params, id
  put<float>(body, 1.f);
  put<float>(body, 2.f);
  put<int16_t>(body, 7);
  put<uint8_t>(body, 0);  // camera 1: empty list, id
  put<int16_t>(body, 8);
  for (int i = 0; i < 2; ++i) {
    put<double>(body, 0.25 + i);
    put<int32_t>(body, -3 - i);
    put<uint16_t>(body, static_cast<uint16_t>(65535 - i));
    put<uint8_t>(body, 9);
    put<float>(body, 0.75f);
    for (int j = 8; j >= 0; --j) put<float>(body, static_cast<float>(100 * i + j));
    for (float v : {0.1f, 1.f, 0.f, 0.f, 0.f, -1.f, -2.f, -3.f}) put<float>(body, v + static_cast<float>(i));
    for (float v : {4.f, 5.f, 6.f}) put<float>(body, v);
  }
  write_bytes(p, h + body);
  const SplatCloud c = read_splat_ply(p);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c.means, (std::vector<float>{0.25f, -3, 65535, 1.25f, -4, 65534}));
  EXPECT_EQ(c.normals, (std::vector<float>{0, 0, 0.75f, 0, 0, 0.75f}));
  EXPECT_EQ(c.sh_rest_per_channel, 3);
  std::vector<float> rest;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 9; ++j) rest.push_back(static_cast<float>(100 * i + j));
  EXPECT_EQ(c.sh_rest, rest);
  EXPECT_EQ(c.opacity_logit, (std::vector<float>{0.1f, 1.1f}));
  EXPECT_EQ(c.rotations, (std::vector<float>{1, 0, 0, 0, 2, 1, 1, 1}));
  EXPECT_EQ(c.log_scales, (std::vector<float>{-1, -2, -3, 0, -1, -2}));
  EXPECT_EQ(c.sh_dc, (std::vector<float>{4, 5, 6, 4, 5, 6}));
}

// ---- compressed PLY ---------------------------------------------------------------------

struct Compressed {
  bool colour_range = true;
  std::vector<std::array<float, 18>> chunks;
  std::vector<std::array<uint32_t, 4>> vertices;  // position, rotation, scale, colour
  int sh_per_splat = 0;                           // 3K bytes per splat
  std::vector<uint8_t> sh;

  std::string header_text() const {
    static const char* names[18] = {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                                    "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z",
                                    "min_r", "min_g", "min_b", "max_r", "max_g", "max_b"};
    std::string h = fmt::format("ply\nformat binary_little_endian 1.0\ncomment Generated by hand\nelement chunk {}\n", chunks.size());
    for (int k = 0; k < (colour_range ? 18 : 12); ++k) h += fmt::format("property float {}\n", names[k]);
    h += fmt::format("element vertex {}\n", vertices.size());
    for (const char* n : {"packed_position", "packed_rotation", "packed_scale", "packed_color"})
      h += fmt::format("property uint {}\n", n);
    if (sh_per_splat) {
      h += fmt::format("element sh {}\n", vertices.size());
      for (int j = 0; j < sh_per_splat; ++j) h += fmt::format("property uchar f_rest_{}\n", j);
    }
    return h + "end_header\n";
  }
  std::string body() const {
    std::string b;
    for (const auto& c : chunks)
      for (int k = 0; k < (colour_range ? 18 : 12); ++k) put<float>(b, c[k]);
    for (const auto& v : vertices)
      for (uint32_t x : v) put<uint32_t>(b, x);
    b.append(reinterpret_cast<const char*>(sh.data()), sh.size());
    return b;
  }
  std::string bytes() const { return header_text() + body(); }
};

uint32_t pack111011(uint32_t x, uint32_t y, uint32_t z) { return (x << 21) | (y << 11) | z; }
uint32_t pack8888(uint32_t r, uint32_t g, uint32_t b, uint32_t a) { return (r << 24) | (g << 16) | (b << 8) | a; }
uint32_t pack_rot(uint32_t largest, uint32_t a, uint32_t b, uint32_t c) { return (largest << 30) | (a << 20) | (b << 10) | c; }

// Packs a quaternion (w, x, y, z) = rot_0..3 the way SuperSplat's writer does.
uint32_t encode_rot(std::array<double, 4> q) {
  const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  int largest = 0;
  for (int k = 0; k < 4; ++k) {
    q[k] /= len;
    if (std::abs(q[k]) > std::abs(q[largest])) largest = k;
  }
  if (q[largest] < 0)
    for (double& v : q) v = -v;
  uint32_t out = static_cast<uint32_t>(largest);
  for (int k = 0; k < 4; ++k)
    if (k != largest)
      out = (out << 10) | static_cast<uint32_t>(std::clamp(std::floor((q[k] * std::sqrt(0.5) + 0.5) * 1023 + 0.5), 0.0, 1023.0));
  return out;
}

Compressed two_chunks() {
  Compressed c;
  const float dc_lo = static_cast<float>(0.5 - kSh0), dc_hi = static_cast<float>(0.5 + kSh0);
  c.chunks.push_back({0, -1, 10, 2047, 1, 20, -5, -6, -7, -1, -2, -3, dc_lo, 0.5f, 0, dc_hi, 0.5f, 1});
  c.chunks.push_back({100, 100, 100, 100, 100, 100, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1});
  for (int i = 0; i < 257; ++i)
    c.vertices.push_back({pack111011(static_cast<uint32_t>(i), 1023, 0), pack_rot(0, 512, 512, 512), pack111011(2047, 0, 1024),
                          pack8888(255, 17, 0, static_cast<uint32_t>(i % 256))});
  return c;
}

TEST(Ply, CompressedDecodesExactlyKnownValues) {
  const fs::path p = test::temp_dir("ply-c") / "c.ply";
  Compressed c = two_chunks();
  write_bytes(p, c.bytes());
  const SplatCloud s = read_splat_ply(p);
  ASSERT_EQ(s.size(), 257u);
  EXPECT_EQ(s.sh_rest_per_channel, 0);
  EXPECT_EQ(s.normals, std::vector<float>(257 * 3, 0.f));
  // Position: x = i (range 0..2047 over 11 bits), y = max (10 bits all set), z = min.
  for (int i : {0, 1, 100, 255}) {
    EXPECT_EQ(s.means[i * 3 + 0], static_cast<float>(i));
    EXPECT_EQ(s.means[i * 3 + 1], 1.f);
    EXPECT_EQ(s.means[i * 3 + 2], 10.f);
  }
  // Splat 256 is in the second chunk, whose range is a single point.
  EXPECT_EQ(s.means[256 * 3 + 0], 100.f);
  EXPECT_EQ(s.means[256 * 3 + 1], 100.f);
  // Log scale: x at max, y at min, z at 1024/2047 of [-7, -3].
  EXPECT_EQ(s.log_scales[0], -1.f);
  EXPECT_EQ(s.log_scales[1], -6.f);
  EXPECT_EQ(s.log_scales[2], static_cast<float>(-7.0 * (1 - 1024.0 / 2047) + -3.0 * (1024.0 / 2047)));
  // Colour: r at the top of [0.5 - SH_C0, 0.5 + SH_C0] -> f_dc 1; g range is a point at
  // 0.5 -> 0; b at the bottom of [0, 1] -> -0.5 / SH_C0.
  EXPECT_FLOAT_EQ(s.sh_dc[0], 1.f);
  EXPECT_NEAR(s.sh_dc[1], 0.f, 1e-6f);
  EXPECT_FLOAT_EQ(s.sh_dc[2], static_cast<float>(-0.5 / kSh0));
  // Opacity: byte 0 and 255 are +-40 (PlayCanvas), others logit(byte / 255).
  EXPECT_EQ(s.opacity_logit[0], -40.f);
  EXPECT_EQ(s.opacity_logit[255], 40.f);
  EXPECT_FLOAT_EQ(s.opacity_logit[51], static_cast<float>(-std::log(4.0)));  // alpha 0.2
  EXPECT_FLOAT_EQ(s.opacity_logit[204], static_cast<float>(std::log(4.0)));  // alpha 0.8
  EXPECT_EQ(s.opacity_logit[256], -40.f);
  // Rotation: index 0 = rot_0 (w) is the dropped largest one; the others are ~0.
  const float small = static_cast<float>((512.0 / 1023 - 0.5) * std::sqrt(2.0));
  EXPECT_FLOAT_EQ(s.rotations[1], small);
  EXPECT_FLOAT_EQ(s.rotations[2], small);
  EXPECT_FLOAT_EQ(s.rotations[3], small);
  EXPECT_FLOAT_EQ(s.rotations[0], static_cast<float>(std::sqrt(1 - 3.0 * small * small)));
}

TEST(Ply, CompressedRotationConvention) {
  // The 2-bit index names which of rot_0..rot_3 (w, x, y, z) was dropped; the other three
  // follow in rot order. Every position of the largest component, and a negative largest
  // one (the writer flips the sign of the whole quaternion).
  const std::vector<std::array<double, 4>> quats = {
      {0.9, 0.1, -0.3, 0.2}, {0.1, 0.9, -0.3, 0.2}, {0.1, -0.3, 0.9, 0.2}, {0.1, -0.3, 0.2, 0.9}, {0.2, -0.8, 0.3, 0.1}};
  Compressed c;
  c.chunks.push_back({});
  for (const auto& q : quats) c.vertices.push_back({0, encode_rot(q), 0, 0});
  EXPECT_EQ(c.vertices[1][1] >> 30, 1u);
  EXPECT_EQ(c.vertices[3][1] >> 30, 3u);
  const fs::path p = test::temp_dir("ply-c") / "rot.ply";
  write_bytes(p, c.bytes());
  const SplatCloud s = read_splat_ply(p);
  for (size_t i = 0; i < quats.size(); ++i) {
    const auto& q = quats[i];
    const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const double sign = i == 4 ? -1 : 1;
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(s.rotations[i * 4 + k], sign * q[k] / len, 2e-3) << i << " " << k;
  }
}

TEST(Ply, CompressedWithoutColourRangeAndWithSh) {
  Compressed c = two_chunks();
  c.colour_range = false;
  c.sh_per_splat = 9;
  for (size_t i = 0; i < c.vertices.size(); ++i)
    for (int j = 0; j < 9; ++j) c.sh.push_back(static_cast<uint8_t>(j == 0 ? 0 : j == 1 ? 255 : j == 2 ? 128 : (i + j) % 256));
  const fs::path p = test::temp_dir("ply-c") / "sh.ply";
  write_bytes(p, c.bytes());
  const SplatCloud s = read_splat_ply(p);
  ASSERT_EQ(s.size(), 257u);
  // Colour bytes are the colour itself: 255 -> 1, 17 -> 17/255, 0 -> 0.
  EXPECT_FLOAT_EQ(s.sh_dc[0], static_cast<float>(0.5 / kSh0));
  EXPECT_FLOAT_EQ(s.sh_dc[1], static_cast<float>((17.0 / 255 - 0.5) / kSh0));
  EXPECT_FLOAT_EQ(s.sh_dc[2], static_cast<float>(-0.5 / kSh0));
  EXPECT_EQ(s.sh_rest_per_channel, 3);
  ASSERT_EQ(s.sh_rest.size(), 257u * 9);
  // Bytes decode to the centre of their bin of [-4, 4), the ends clamp to -4 and 4.
  EXPECT_EQ(s.sh_rest[0], -4.f);
  EXPECT_EQ(s.sh_rest[1], 4.f);
  EXPECT_EQ(s.sh_rest[2], 0.015625f);  // (128.5 / 256 - 0.5) * 8
  EXPECT_EQ(s.sh_rest[256 * 9 + 3], ((static_cast<float>((256 + 3) % 256) + 0.5f) / 256.f - 0.5f) * 8.f);
}

TEST(Ply, RealCompressedGuitarAndBiker) {
  II_REQUIRE_SHARED(p, "data/splats/guitar.compressed.ply");
  const SplatCloud c = read_splat_ply(p);
  ASSERT_EQ(c.size(), 90854u);
  EXPECT_EQ(c.sh_rest_per_channel, 0);
  float lo[3] = {1e9f, 1e9f, 1e9f}, hi[3] = {-1e9f, -1e9f, -1e9f};
  for (size_t i = 0; i < c.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], c.means[i * 3 + a]);
      hi[a] = std::max(hi[a], c.means[i * 3 + a]);
      ASSERT_TRUE(std::isfinite(c.sh_dc[i * 3 + a]) && std::isfinite(c.log_scales[i * 3 + a]));
    }
    const float* q = &c.rotations[i * 4];
    ASSERT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0f, 1e-5f);
    ASSERT_GE(c.opacity_logit[i], -40.f);
    ASSERT_LE(c.opacity_logit[i], 40.f);
  }
  // PROVENANCE.md: the guitar extends along -y, y in [-4.29, 0.09].
  EXPECT_NEAR(lo[1], -4.29f, 0.005f);
  EXPECT_NEAR(hi[1], 0.09f, 0.005f);

  // Splat 0 and splat 256 decoded by hand from the file's bytes: the first two chunks and
  // the vertex rows after the 355 chunks of 18 floats.
  const std::string bytes = file_bytes(p);
  const size_t chunk0 = bytes.find("end_header\n") + 11, vertex0 = chunk0 + 355 * 18 * 4;
  for (size_t i : {size_t{0}, size_t{256}, size_t{90853}}) {
    float ch[18];
    std::memcpy(ch, bytes.data() + chunk0 + (i / 256) * 72, 72);
    uint32_t v[4];
    std::memcpy(v, bytes.data() + vertex0 + i * 16, 16);
    const double tx = (v[0] >> 21) / 2047.0, ty = ((v[0] >> 11) & 1023) / 1023.0, tz = (v[0] & 2047) / 2047.0;
    EXPECT_FLOAT_EQ(c.means[i * 3 + 0], static_cast<float>(ch[0] * (1 - tx) + ch[3] * tx));
    EXPECT_FLOAT_EQ(c.means[i * 3 + 1], static_cast<float>(ch[1] * (1 - ty) + ch[4] * ty));
    EXPECT_FLOAT_EQ(c.means[i * 3 + 2], static_cast<float>(ch[2] * (1 - tz) + ch[5] * tz));
    const double sx = (v[2] >> 21) / 2047.0;
    EXPECT_FLOAT_EQ(c.log_scales[i * 3 + 0], static_cast<float>(ch[6] * (1 - sx) + ch[9] * sx));
    const double r = (v[3] >> 24) / 255.0;
    EXPECT_FLOAT_EQ(c.sh_dc[i * 3 + 0], static_cast<float>((ch[12] * (1 - r) + ch[15] * r - 0.5) / kSh0));
    const double alpha = (v[3] & 255) / 255.0;
    if (alpha > 0 && alpha < 1) {
      EXPECT_FLOAT_EQ(c.opacity_logit[i], static_cast<float>(std::log(alpha / (1 - alpha))));
    }
    // rot_k for k = the 2-bit index is the dropped one; the others follow in rot order.
    double q[4], others[3] = {((v[1] >> 20) & 1023) / 1023.0, ((v[1] >> 10) & 1023) / 1023.0, (v[1] & 1023) / 1023.0};
    for (double& o : others) o = (o - 0.5) * std::sqrt(2.0);
    for (int k = 0, o = 0; k < 4; ++k)
      q[k] = k == static_cast<int>(v[1] >> 30)
                 ? std::sqrt(1 - others[0] * others[0] - others[1] * others[1] - others[2] * others[2])
                 : others[o++];
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(c.rotations[i * 4 + k], q[k], 1e-6) << i << " " << k;
  }

  II_REQUIRE_SHARED(b, "data/splats/biker.compressed.ply");
  const SplatCloud biker = read_splat_ply(b);
  ASSERT_EQ(biker.size(), 152746u);
  float ylo = 1e9f, yhi = -1e9f;
  for (size_t i = 0; i < biker.size(); ++i) {
    ylo = std::min(ylo, biker.means[i * 3 + 1]);
    yhi = std::max(yhi, biker.means[i * 3 + 1]);
  }
  EXPECT_NEAR(ylo, -3.18f, 0.005f);
  EXPECT_NEAR(yhi, 0.0f, 0.005f);
}

TEST(Ply, DecodedCompressedCloudRoundTripsThroughTheStandardLayout) {
  II_REQUIRE_SHARED(p, "data/splats/guitar.compressed.ply");
  const SplatCloud c = read_splat_ply(p);
  const fs::path out = test::temp_dir("ply") / "guitar.ply";
  write_splat_ply(out, c);
  expect_same(read_splat_ply(out), c);
}

// ---- bad input ---------------------------------------------------------------------------

class PlyBad : public ::testing::Test {
 protected:
  fs::path dir = test::temp_dir("ply-bad");
  std::string error(const std::string& name, const std::string& bytes) {
    write_bytes(dir / name, bytes);
    const std::string msg = test::error_message([&] { read_splat_ply(dir / name); });
    const std::string prefix = (dir / name).string() + ": ";
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
    return msg.substr(std::min(msg.size(), prefix.size()));
  }
};

std::string standard_header(size_t n, const std::string& format = "binary_little_endian") {
  std::string h = fmt::format("ply\nformat {} 1.0\nelement vertex {}\n", format, n);
  for (const char* p : {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0",
                        "rot_1", "rot_2", "rot_3"})
    h += fmt::format("property float {}\n", p);
  return h + "end_header\n";
}

TEST_F(PlyBad, NotAPlyFile) {
  EXPECT_EQ(error("upper.ply", "PLY\n"), "not a PLY file (missing 'ply' magic)");
  EXPECT_EQ(error("empty.ply", ""), "not a PLY file (missing 'ply' magic)");
  EXPECT_EQ(error("plyx.ply", "plyx\nformat ascii 1.0\nend_header\n"), "not a PLY file (missing 'ply' magic)");
  EXPECT_EQ(error("npy.ply", "\x93NUMPY\x01\x00"), "not a PLY file (missing 'ply' magic)");
  EXPECT_EQ(error("noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"), "PLY header has no end_header line");
}

TEST_F(PlyBad, WrongFormatLine) {
  EXPECT_EQ(error("big.ply", "ply\nformat binary_big_endian 1.0\nend_header\n"),
            "unsupported PLY format 'binary_big_endian' (binary_little_endian or ascii)");
  EXPECT_EQ(error("v2.ply", "ply\nformat ascii 2.0\nend_header\n"), "unsupported PLY version '2.0' (1.0)");
  EXPECT_EQ(error("short.ply", "ply\nformat ascii\nend_header\n"), "malformed PLY format line 'format ascii'");
  EXPECT_EQ(error("none.ply", "ply\nelement vertex 0\nend_header\n"), "PLY header has no format line");
  EXPECT_EQ(error("two.ply", "ply\nformat ascii 1.0\nformat ascii 1.0\nend_header\n"), "PLY header has two format lines");
}

TEST_F(PlyBad, MalformedHeaderLines) {
  EXPECT_EQ(error("type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n"),
            "unknown PLY property type 'float128'");
  EXPECT_EQ(error("listtype.ply", "ply\nformat ascii 1.0\nelement face 1\nproperty list float int idx\nend_header\n"),
            "PLY list property 'idx' has a non-integer count type float");
  EXPECT_EQ(error("count.ply", "ply\nformat ascii 1.0\nelement vertex -5\nend_header\n"),
            "malformed PLY element line 'element vertex -5'");
  EXPECT_EQ(error("count2.ply", "ply\nformat ascii 1.0\nelement vertex 12abc\nend_header\n"),
            "malformed PLY element line 'element vertex 12abc'");
  EXPECT_EQ(error("orphan.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
            "PLY property before any element: 'property float x'");
  EXPECT_EQ(error("prop.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float\nend_header\n"),
            "malformed PLY property line 'property float'");
  EXPECT_EQ(error("dupprop.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty int x\nend_header\n"),
            "vertex element declares property 'x' twice");
  EXPECT_EQ(error("dupel.ply", "ply\nformat ascii 1.0\nelement vertex 1\nelement vertex 1\nend_header\n"),
            "PLY header declares element 'vertex' twice");
  EXPECT_EQ(error("junk.ply", "ply\nformat ascii 1.0\nvertices 5\nend_header\n"), "unexpected PLY header line 'vertices 5'");
  EXPECT_EQ(error("binary.ply", std::string("ply\nformat ascii 1.0\n\x01\x02\xff\n", 25)), "unexpected PLY header line '?\?\?'");
}

TEST_F(PlyBad, MissingRequiredProperties) {
  EXPECT_EQ(error("novertex.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n"), "PLY file has no vertex element");
  EXPECT_EQ(error("one.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"),
            "vertex element lacks required properties y, z, f_dc_0, f_dc_1, f_dc_2, opacity, scale_0, scale_1, "
            "scale_2, rot_0, rot_1, rot_2, rot_3 (a 3D Gaussian splat PLY needs x y z f_dc_0..2 opacity scale_0..2 "
            "rot_0..3)");
  std::string h = standard_header(1);
  h.replace(h.find("property float opacity\n"), 23, "");
  EXPECT_EQ(error("opacity.ply", h + std::string(13 * 4, '\0')),
            "vertex element lacks required property opacity (a 3D Gaussian splat PLY needs x y z f_dc_0..2 opacity "
            "scale_0..2 rot_0..3)");
  // A standard file that is an ordinary point cloud.
  EXPECT_EQ(error("points.ply",
                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                  "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n0 0 0 255 0 0\n"),
            "vertex element lacks required properties f_dc_0, f_dc_1, f_dc_2, opacity, scale_0, scale_1, scale_2, "
            "rot_0, rot_1, rot_2, rot_3 (a 3D Gaussian splat PLY needs x y z f_dc_0..2 opacity scale_0..2 rot_0..3)");
}

TEST_F(PlyBad, BadShCoefficientSets) {
  std::string h = standard_header(1);
  std::string rest;
  for (int j = 0; j < 9; ++j)
    if (j != 4) rest += fmt::format("property float f_rest_{}\n", j);
  h.insert(h.find("end_header"), rest);
  EXPECT_EQ(error("gap.ply", h + std::string(22 * 4, '\0')), "vertex element has 8 f_rest properties but no f_rest_4");
  std::string h6 = standard_header(1);
  std::string rest6;
  for (int j = 0; j < 6; ++j) rest6 += fmt::format("property float f_rest_{}\n", j);
  h6.insert(h6.find("end_header"), rest6);
  EXPECT_EQ(error("six.ply", h6 + std::string(20 * 4, '\0')),
            "vertex element has 6 f_rest properties; expected 0, 9, 24 or 45 (SH degree 0 to 3)");
}

TEST_F(PlyBad, TruncatedOrLyingBody) {
  EXPECT_EQ(error("lying.ply", standard_header(1000) + std::string(40, '\0')),
            "truncated PLY body: 1000 vertex rows of 56 bytes do not fit in the 40 bytes left");
  EXPECT_EQ(error("huge.ply", standard_header(4000000000ULL) + std::string(56, '\0')),
            "truncated PLY body: 4000000000 vertex rows of 56 bytes do not fit in the 56 bytes left");
  EXPECT_EQ(error("max.ply", standard_header(18446744073709551615ULL)),
            "truncated PLY body: 18446744073709551615 vertex rows of 56 bytes do not fit in the 0 bytes left");
  // A real file cut in half.
  write_splat_ply(dir / "good.ply", sample_cloud(100, 0));
  const std::string good = file_bytes(dir / "good.ply");
  const size_t body = good.size() - 100 * 68;
  EXPECT_EQ(error("half.ply", good.substr(0, good.size() / 2)),
            fmt::format("truncated PLY body: 100 vertex rows of 68 bytes do not fit in the {} bytes left",
                        good.size() / 2 - body));
  // One byte short.
  EXPECT_EQ(error("short.ply", good.substr(0, good.size() - 1)),
            "truncated PLY body: 100 vertex rows of 68 bytes do not fit in the 6799 bytes left");
  // A list element whose rows run past the end.
  const std::string faces = "ply\nformat binary_little_endian 1.0\nelement vertex 0\nelement face 2\n";
  EXPECT_EQ(error("list.ply", faces + "property list uchar int idx\nend_header\n" + std::string("\x01\x00\x00\x00\x00\xff", 6)),
            "truncated PLY body: list of 255 items in face row 1 does not fit in the 0 bytes left");
  EXPECT_EQ(error("listneg.ply", faces + "property list char int idx\nend_header\n\xfe"), "negative list length -2 in face row 0");
  const std::string cut = faces + "property list int int idx\nend_header\n\x01";
  EXPECT_EQ(error("listcut.ply", cut),
            fmt::format("truncated file: needs 4 more bytes for list length at byte {}, only 1 left", cut.size() - 1));
  // A list property in the vertex element itself.
  EXPECT_EQ(error("vlist.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty list uchar float x\nend_header\n" +
                                   std::string(1, '\0')),
            "list properties are not supported in the vertex element");
}

TEST_F(PlyBad, TruncatedOrMalformedAsciiBody) {
  const std::string h = standard_header(2, "ascii");
  const std::string row = "1 2 3 4 5 6 7 8 9 10 11 12 13 14\n";
  EXPECT_EQ(error("few.ply", h + row + "1 2 3 4 5 6 7 8 9 10 11 12 13\n"),
            "truncated ASCII PLY body: vertex row 1 of 2 has too few values");
  EXPECT_EQ(error("nan.ply", h + row + "1 2 3 4 5 6 7 8 9 10 11 x 13 14\n"), "malformed number 'x' in ASCII PLY body (vertex row 1)");
  EXPECT_EQ(error("comma.ply", h + row + "1,2 3 4 5 6 7 8 9 10 11 12 13 14\n"),
            "malformed number '1,2' in ASCII PLY body (vertex row 1)");
  // A count the file cannot hold is refused before anything is allocated.
  EXPECT_EQ(error("lying.ply", standard_header(3000000000ULL, "ascii") + row),
            "truncated ASCII PLY body: 3000000000 vertex rows of 14 values do not fit in the 33 bytes left");
  EXPECT_EQ(error("list.ply", "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int idx\nelement vertex 0\nend_header\n-1\n"),
            "bad list length -1 in ASCII PLY body (face row 0)");
}

TEST_F(PlyBad, BadCompressedFiles) {
  const Compressed good = two_chunks();
  std::string ascii = good.header_text();
  ascii.replace(ascii.find("binary_little_endian"), 20, "ascii");
  EXPECT_EQ(error("ascii.ply", ascii), "compressed PLY must be binary, not ascii");
  // Truncated: the vertex rows run past the end.
  const std::string bytes = good.bytes();
  EXPECT_EQ(error("cut.ply", bytes.substr(0, bytes.size() - 10)),
            "truncated PLY body: 257 vertex rows of 16 bytes do not fit in the 4102 bytes left");
  // No chunk element.
  Compressed nochunk = good;
  nochunk.chunks.clear();
  std::string h = nochunk.header_text();
  h.erase(h.find("element chunk"), h.find("element vertex") - h.find("element chunk"));
  EXPECT_EQ(error("nochunk.ply", h + nochunk.body()), "compressed PLY (packed_* vertex properties) has no chunk element");
  // Too few chunks for the splats.
  Compressed few = good;
  few.chunks.pop_back();
  EXPECT_EQ(error("few.ply", few.bytes()), "compressed PLY has 1 chunks for 257 splats (256 splats per chunk: needs 2)");
  // Packed properties of the wrong type or missing.
  std::string t = good.bytes();
  t.replace(t.find("property uint packed_scale"), 26, "property float packed_scale");
  EXPECT_EQ(error("type.ply", t), "compressed PLY property 'packed_scale' must be uint32, not float");
  std::string m = good.bytes();
  m.replace(m.find("property uint packed_color"), 26, "property uint something_else");
  EXPECT_EQ(error("missing.ply", m),
            "vertex element lacks required property packed_color (compressed PLY)");
  // A chunk range property missing, or only part of the colour range.
  std::string r = good.bytes();
  r.replace(r.find("property float min_y\n"), 20, "property float wrong");
  EXPECT_EQ(error("range.ply", r), "chunk element lacks required property min_y (compressed PLY)");
  std::string part = good.bytes();
  part.replace(part.find("property float max_g\n"), 20, "property float max_q");
  EXPECT_EQ(error("colour.ply", part), "chunk element lacks required property max_g (compressed PLY colour range)");
}

TEST_F(PlyBad, BadCompressedSh) {
  Compressed c = two_chunks();
  c.sh_per_splat = 9;
  c.sh.assign(257 * 9, 128);
  std::string rows = c.bytes();
  rows.replace(rows.find("element sh 257"), 14, "element sh 256");
  EXPECT_EQ(error("rows.ply", rows.substr(0, rows.size() - 9)), "sh element has 256 rows for 257 splats");
  std::string type = c.bytes();
  type.replace(type.find("property uchar f_rest_3"), 23, "property char f_rest_3");
  EXPECT_EQ(error("type.ply", type), "sh property 'f_rest_3' must be uchar, not char");
  std::string name = c.bytes();
  name.replace(name.find("property uchar f_rest_8"), 23, "property uchar f_rest_9");
  EXPECT_EQ(error("name.ply", name), "sh element lacks required property f_rest_8 (compressed PLY)");
  Compressed six = two_chunks();
  six.sh_per_splat = 6;
  six.sh.assign(257 * 6, 0);
  EXPECT_EQ(error("six.ply", six.bytes()), "sh element has 6 properties; expected 9, 24 or 45 (SH degree 1 to 3)");
}

// The compressed writer's splats come back in Morton order, each attribute within half a
// quantisation step of its chunk's range (the range the writer took from the splats).
TEST(Ply, CompressedWriteRoundTripsWithinItsQuantisation) {
  for (int rest : {0, 3, 15}) {
    SplatCloud c = sample_cloud(700, rest);  // three chunks, the last one partial
    for (size_t i = 0; i < c.size(); ++i) {
      c.means[i * 3 + 1] = std::sin(0.37f * static_cast<float>(i)) * 4;  // not already in Morton order
      for (int k = 0; k < 3 * rest; ++k) c.sh_rest[i * 3 * rest + k] = std::cos(0.1f * static_cast<float>(i + k));
    }
    const fs::path p = test::temp_dir("ply-c") / fmt::format("c{}.compressed.ply", rest);
    write_compressed_splat_ply(p, c);
    const SplatCloud d = read_splat_ply(p);
    const std::vector<size_t> order = morton_order(c.means);
    ASSERT_EQ(d.size(), c.size());
    ASSERT_EQ(d.sh_rest_per_channel, rest);
    for (size_t s = 0; s < d.size(); ++s) {
      const size_t i = order[s], chunk = s / 256;
      auto range = [&](const std::vector<float>& v, int a, double (*f)(double)) {
        double lo = 1e30, hi = -1e30;
        for (size_t t = chunk * 256; t < std::min(d.size(), chunk * 256 + 256); ++t) {
          lo = std::min(lo, f(v[order[t] * 3 + a]));
          hi = std::max(hi, f(v[order[t] * 3 + a]));
        }
        return hi - lo;
      };
      auto same = [](double v) { return v; };
      auto colour = [](double dc) { return 0.5 + kSh0 * dc; };
      for (int a = 0; a < 3; ++a) {
        const int bits = a == 1 ? 10 : 11;
        ASSERT_NEAR(d.means[s * 3 + a], c.means[i * 3 + a], range(c.means, a, same) / ((1 << bits) - 1) / 2 + 1e-5);
        ASSERT_NEAR(d.log_scales[s * 3 + a], c.log_scales[i * 3 + a],
                    range(c.log_scales, a, same) / ((1 << bits) - 1) / 2 + 1e-5);
        ASSERT_NEAR(colour(d.sh_dc[s * 3 + a]), colour(c.sh_dc[i * 3 + a]), range(c.sh_dc, a, colour) / 255 / 2 + 1e-5);
      }
      const double alpha_c = 1 / (1 + std::exp(-c.opacity_logit[i])), alpha_d = 1 / (1 + std::exp(-d.opacity_logit[s]));
      ASSERT_NEAR(alpha_d, alpha_c, 0.5 / 255 + 1e-6);
      double dot = 0, norm = 0;
      for (int k = 0; k < 4; ++k) {
        dot += double(d.rotations[s * 4 + k]) * c.rotations[i * 4 + k];
        norm += double(c.rotations[i * 4 + k]) * c.rotations[i * 4 + k];
      }
      ASSERT_GT(std::abs(dot) / std::sqrt(norm), std::cos(0.004 / 2)) << s;  // within 0.004 rad
      for (int k = 0; k < 3 * rest; ++k)  // 8 bits over [-4, 4]: one bin, 8/256
        ASSERT_NEAR(d.sh_rest[s * 3 * rest + k], c.sh_rest[i * 3 * rest + k], 8.0 / 256 + 1e-6);
    }
  }
}

// morton_order against a plain reference: 10 bits per axis interleaved bit by bit (z highest),
// then std::stable_sort; ties keep their order.
TEST(Ply, MortonOrderIsAStableSortByInterleavedCodes) {
  std::mt19937 random(11);
  std::uniform_real_distribution<float> u(-3.f, 5.f);
  std::vector<float> means(3 * 20000);
  for (float& m : means) m = u(random);
  for (size_t i = 100; i < 200; ++i)  // duplicates of one point: ties
    for (int a = 0; a < 3; ++a) means[i * 3 + a] = means[a];
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  const size_t n = means.size() / 3;
  for (size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], means[i * 3 + a]);
      hi[a] = std::max(hi[a], means[i * 3 + a]);
    }
  std::vector<uint32_t> code(n, 0);
  for (size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) {
      const double t = (means[i * 3 + a] - lo[a]) / (static_cast<double>(hi[a]) - lo[a]);
      const auto q = static_cast<uint32_t>(std::clamp(t, 0.0, 1.0) * 1023);
      for (int bit = 0; bit < 10; ++bit) code[i] |= ((q >> bit) & 1u) << (3 * bit + a);
    }
  std::vector<size_t> expected(n);
  for (size_t i = 0; i < n; ++i) expected[i] = i;
  std::stable_sort(expected.begin(), expected.end(), [&](size_t a, size_t b) { return code[a] < code[b]; });
  EXPECT_EQ(morton_order(means), expected);
}

TEST(Ply, WriteRefusesInconsistentClouds) {
  const fs::path p = test::temp_dir("ply-w") / "w.ply";
  SplatCloud c = sample_cloud(3, 3);
  c.means.pop_back();
  EXPECT_EQ(test::error_message([&] { write_splat_ply(p, c); }),
            p.string() + ": splat cloud means has 8 values, expected 9 (3 per splat for 3 splats)");
  c = sample_cloud(3, 3);
  c.sh_rest_per_channel = 8;
  EXPECT_EQ(test::error_message([&] { write_splat_ply(p, c); }),
            p.string() + ": splat cloud sh_rest has 27 values, expected 72 (24 per splat for 3 splats)");
  c = sample_cloud(3, 0);
  c.rotations.resize(9);
  EXPECT_EQ(test::error_message([&] { write_splat_ply(p, c); }),
            p.string() + ": splat cloud rotations has 9 values, expected 12 (4 per splat for 3 splats)");
  EXPECT_FALSE(fs::exists(p));
}

}  // namespace ply_test
}  // namespace
}  // namespace ii
