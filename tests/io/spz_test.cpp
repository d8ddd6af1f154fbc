// SPZ: exact decoding of hand-made files of each version (2: gzip, first-three rotations;
// 3: gzip, smallest-three rotations; 4: zstd streams), round trips within each attribute's
// quantisation, the splat-file dispatch by name, and bad input with its exact message.
#include <gtest/gtest.h>
#include <zlib.h>
#include <zstd.h>

#include <cmath>
#include <cstring>
#include <random>

#include "common/files.h"
#include "io/splat_file.h"
#include "io/spz.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace spz_test {

namespace fs = std::filesystem;

template <typename T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

std::string gzip(const std::string& plain) {
  z_stream s{};
  deflateInit2(&s, 6, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
  std::string out(deflateBound(&s, plain.size()), '\0');
  s.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(plain.data()));
  s.avail_in = static_cast<uInt>(plain.size());
  s.next_out = reinterpret_cast<Bytef*>(out.data());
  s.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&s, Z_FINISH), Z_STREAM_END);
  out.resize(out.size() - s.avail_out);
  deflateEnd(&s);
  return out;
}

std::string header(uint32_t version, uint32_t n, uint8_t degree, uint8_t bits) {
  std::string h;
  put(h, 0x5053474eu);
  put(h, version);
  put(h, n);
  put(h, degree);
  put(h, bits);
  put(h, uint8_t{0});
  put(h, uint8_t{0});
  return h;
}

// One splat, degree 1: position (1.5, -2.25, 0.001) at 12 fractional bits, alpha byte 191,
// colour bytes (128, 0, 255), scale bytes (160, 0, 255), SH bytes 0..8 x 30.
struct OneSplat {
  std::string positions, alphas{char(191)}, colours{char(128), char(0), char(255)},
      scales{char(160), char(0), char(255)}, sh;
  OneSplat() {
    for (int32_t fixed : {6144, -9216, 4}) {  // x 4096
      positions += static_cast<char>(fixed & 0xff);
      positions += static_cast<char>((fixed >> 8) & 0xff);
      positions += static_cast<char>((fixed >> 16) & 0xff);
    }
    for (int k = 0; k < 9; ++k) sh += static_cast<char>(k * 30);
  }
  void expect(const SplatCloud& c) const {
    ASSERT_EQ(c.size(), 1u);
    EXPECT_EQ(c.means, (std::vector<float>{1.5f, -2.25f, 4 / 4096.f}));
    EXPECT_FLOAT_EQ(c.opacity_logit[0], static_cast<float>(std::log((191 / 255.0) / (1 - 191 / 255.0))));
    EXPECT_FLOAT_EQ(c.sh_dc[0], static_cast<float>((128 / 255.0 - 0.5) / 0.15));
    EXPECT_FLOAT_EQ(c.sh_dc[1], static_cast<float>(-0.5 / 0.15));
    EXPECT_FLOAT_EQ(c.sh_dc[2], static_cast<float>(0.5 / 0.15));
    EXPECT_EQ(c.log_scales, (std::vector<float>{0.f, -10.f, 255 / 16.f - 10.f}));
    ASSERT_EQ(c.sh_rest_per_channel, 3);
    // SPZ: coefficient-major, colour inner; PLY: channel-major.
    for (int j = 0; j < 3; ++j)
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_FLOAT_EQ(c.sh_rest[ch * 3 + j], ((j * 3 + ch) * 30 - 128) / 128.f) << j << " " << ch;
  }
};

fs::path write(const std::string& name, const std::string& bytes) {
  const fs::path p = test::temp_dir("spz") / name;
  test::write_bytes(p, bytes);
  return p;
}

TEST(Spz, Version2DecodesExactly) {
  const OneSplat s;
  // Rotation x, y, z as bytes: (255, 127.5 -> 128, 0) ~ (1, 0, -1)/..., here (153, 127, 102).
  const std::string rotation{char(153), char(127), char(102)};
  const SplatCloud c = read_spz(
      write("v2.spz", gzip(header(2, 1, 1, 12) + s.positions + s.alphas + s.colours + s.scales + rotation + s.sh)));
  s.expect(c);
  const double x = 153 / 127.5 - 1, y = 127 / 127.5 - 1, z = 102 / 127.5 - 1;
  EXPECT_FLOAT_EQ(c.rotations[0], static_cast<float>(std::sqrt(1 - x * x - y * y - z * z)));  // w
  EXPECT_FLOAT_EQ(c.rotations[1], static_cast<float>(x));
  EXPECT_FLOAT_EQ(c.rotations[2], static_cast<float>(y));
  EXPECT_FLOAT_EQ(c.rotations[3], static_cast<float>(z));
}

// Smallest three: index of the largest (x, y, z, w order) in the top 2 bits, then the others
// in that order, sign bit + 9 bits of |q| / √½ each.
uint32_t smallest_three(int largest, const std::vector<std::pair<bool, uint32_t>>& others) {
  uint32_t packed = static_cast<uint32_t>(largest);
  for (auto [negative, magnitude] : others) packed = packed << 10 | (negative ? 512u : 0u) | magnitude;
  return packed;
}

TEST(Spz, Version3DecodesExactly) {
  const OneSplat s;
  // Largest w (index 3); x = +100/511 √½, y = -200/511 √½, z = 0.
  std::string rotation;
  put(rotation, smallest_three(3, {{false, 100}, {true, 200}, {false, 0}}));
  const SplatCloud c = read_spz(
      write("v3.spz", gzip(header(3, 1, 1, 12) + s.positions + s.alphas + s.colours + s.scales + rotation + s.sh)));
  s.expect(c);
  const double h = std::sqrt(0.5), x = h * 100 / 511, y = -h * 200 / 511;
  EXPECT_FLOAT_EQ(c.rotations[0], static_cast<float>(std::sqrt(1 - x * x - y * y)));
  EXPECT_FLOAT_EQ(c.rotations[1], static_cast<float>(x));
  EXPECT_FLOAT_EQ(c.rotations[2], static_cast<float>(y));
  EXPECT_FLOAT_EQ(c.rotations[3], 0.f);
}

std::string zstd_stream(const std::string& plain) {
  std::string out(ZSTD_compressBound(plain.size()), '\0');
  out.resize(ZSTD_compress(out.data(), out.size(), plain.data(), plain.size(), 3));
  return out;
}

std::string version4(const std::vector<std::string>& streams, uint32_t n, uint8_t degree, uint32_t toc = 32) {
  std::string f;
  put(f, 0x5053474eu);
  put(f, 4u);
  put(f, n);
  put(f, degree);
  put(f, uint8_t{12});
  put(f, uint8_t{0});
  put(f, static_cast<uint8_t>(streams.size()));
  put(f, toc);
  f += std::string(12, '\0');
  f += std::string(toc - 32, 'x');  // extension records, skipped
  std::string body;
  for (const std::string& s : streams) {
    const std::string z = zstd_stream(s);
    put(f, static_cast<uint64_t>(z.size()));
    put(f, static_cast<uint64_t>(s.size()));
    body += z;
  }
  return f + body;
}

TEST(Spz, Version4DecodesExactly) {
  const OneSplat s;
  std::string rotation;
  put(rotation, smallest_three(0, {{false, 0}, {false, 0}, {false, 511}}));  // x largest, w = √½
  const SplatCloud c =
      read_spz(write("v4.spz", version4({s.positions, s.alphas, s.colours, s.scales, rotation, s.sh}, 1, 1, 40)));
  s.expect(c);
  EXPECT_FLOAT_EQ(c.rotations[0], static_cast<float>(std::sqrt(0.5)));  // w
  EXPECT_FLOAT_EQ(c.rotations[1], static_cast<float>(std::sqrt(0.5)));  // x, the largest
  // Degree 0 has five streams (no SH).
  const SplatCloud d = read_spz(write("v4-degree0.spz", version4({s.positions, s.alphas, s.colours, s.scales, rotation}, 1, 0)));
  EXPECT_EQ(d.sh_rest_per_channel, 0);
  EXPECT_EQ(d.means, c.means);
}

TEST(Spz, RoundTripsWithinEachAttributesQuantisation) {
  for (int rest : {0, 3, 8, 15}) {
    const SplatCloud c = test::random_splats(500, rest, 7 + rest, 20.f);
    const fs::path p = test::temp_dir("spz") / fmt::format("round-{}.spz", rest);
    write_splats(p, c);
    const SplatCloud d = read_splats(p);
    ASSERT_EQ(d.size(), c.size());
    ASSERT_EQ(d.sh_rest_per_channel, rest);
    for (size_t i = 0; i < c.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        ASSERT_NEAR(d.means[i * 3 + a], c.means[i * 3 + a], 0.5 / 4096 + 1e-6);  // 12 fractional bits
        ASSERT_NEAR(d.log_scales[i * 3 + a], c.log_scales[i * 3 + a], 0.5 / 16 + 1e-6);
        ASSERT_NEAR(d.sh_dc[i * 3 + a], c.sh_dc[i * 3 + a], 0.5 / (0.15 * 255) + 1e-6);
      }
      const double sigmoid_c = 1 / (1 + std::exp(-c.opacity_logit[i])), sigmoid_d = 1 / (1 + std::exp(-d.opacity_logit[i]));
      ASSERT_NEAR(sigmoid_d, sigmoid_c, 0.5 / 255 + 1e-6);
      ASSERT_LT(test::rotation_angle(&d.rotations[i * 4], &c.rotations[i * 4]), 0.004) << i;  // radians
      for (int ch = 0; ch < 3; ++ch)
        for (int j = 0; j < rest; ++j) {
          const size_t k = i * 3 * rest + ch * rest + j;
          // All 8 bits: half a step of 1/128.
          ASSERT_NEAR(d.sh_rest[k], c.sh_rest[k], 0.5 / 128 + 1e-6) << i << " " << j;
        }
    }
  }
}

TEST(Spz, NoSplatsReadAsNoSplats) {
  SplatCloud none;
  none.sh_rest_per_channel = 3;
  const std::vector<uint8_t> bytes = encode_spz(none, "none.spz");
  EXPECT_EQ(decode_spz(bytes.data(), bytes.size(), "none.spz").size(), 0u);
  EXPECT_EQ(read_spz(write("none-v4.spz", version4({"", "", "", "", "", ""}, 0, 1))).size(), 0u);
}

TEST(Spz, FarPositionsGetFewerFractionalBits) {
  SplatCloud c = test::random_splats(4, 0, 3, 20.f);
  c.means[0] = 3000.25f;  // beyond 2^23 / 4096 = 2048: 11 bits
  const std::vector<uint8_t> bytes = encode_spz(c, "far.spz");
  const SplatCloud d = decode_spz(bytes.data(), bytes.size(), "far.spz");
  EXPECT_FLOAT_EQ(d.means[0], 3000.25f);
  EXPECT_NEAR(d.means[1], c.means[1], 0.5 / 2048 + 1e-6);
  c.means[0] = 1e7f;
  EXPECT_EQ(test::error_message([&] { encode_spz(c, "far.spz"); }),
            "far.spz: a splat position (10000000) is too far from the origin for SPZ's 24-bit positions");
}

TEST(SplatFile, FormatFollowsTheName) {
  EXPECT_EQ(splat_format_of("a/x.PLY"), SplatFormat::Ply);
  EXPECT_EQ(splat_format_of("x.compressed.ply"), SplatFormat::CompressedPly);
  EXPECT_EQ(splat_format_of("x.spz"), SplatFormat::Spz);
  EXPECT_EQ(test::error_message([] { splat_format_of("x.splat"); }),
            "x.splat: not a splat file name: use .ply (3DGS), .compressed.ply (SuperSplat), .spz (Niantic) or .sog "
            "(PlayCanvas)");
}

// ---- bad input ---------------------------------------------------------------------------

std::string error_of(const std::string& name, const std::string& bytes) {
  const fs::path p = write(name, bytes);
  const std::string msg = test::error_message([&] { read_spz(p); });
  const std::string prefix = p.string() + ": ";
  EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
  return msg.substr(std::min(msg.size(), prefix.size()));
}

TEST(SpzBad, EachProblemHasItsMessage) {
  const OneSplat s;
  std::string rotation;
  put(rotation, smallest_three(3, {{false, 0}, {false, 0}, {false, 0}}));
  const std::string body = s.positions + s.alphas + s.colours + s.scales + rotation + s.sh;
  EXPECT_EQ(error_of("text.spz", "hello"),
            "not an SPZ file: neither gzip-compressed (versions 1-3) nor starting with NGSP (version 4)");
  EXPECT_EQ(error_of("magic.spz", gzip("XXXX" + header(3, 1, 1, 12).substr(4) + body)),
            "not an SPZ file (magic 0x58585858, expected 0x5053474e)");
  EXPECT_EQ(error_of("version.spz", gzip(header(9, 1, 1, 12) + body)), "SPZ version 9 is not supported (1 to 4)");
  EXPECT_EQ(error_of("degree.spz", gzip(header(3, 1, 5, 12) + body)), "SPZ SH degree 5 is not supported (0 to 4)");
  EXPECT_EQ(error_of("bits.spz", gzip(header(3, 1, 1, 30) + body)),
            "SPZ fractional bits 30 do not fit 24-bit positions");
  EXPECT_EQ(error_of("short-header.spz", gzip(header(3, 1, 1, 12).substr(0, 10))),
            "truncated SPZ file: 10 bytes, shorter than its header");
  EXPECT_EQ(error_of("lying-count.spz", gzip(header(3, 1000000, 1, 12) + body)),
            "truncated SPZ file: its 1000000 splats need 9000000 bytes of positions, 29 are left");
  EXPECT_EQ(error_of("no-sh.spz", gzip(header(3, 1, 1, 12) + body.substr(0, body.size() - 9))),
            "truncated SPZ file: its 1 splats need 9 bytes of SH, 0 are left");
  const std::string z = gzip(header(3, 1, 1, 12) + body);
  EXPECT_EQ(error_of("cut-gzip.spz", z.substr(0, z.size() / 2)).rfind("truncated SPZ file", 0), 0u);
  std::string corrupt = z;
  corrupt[12] = static_cast<char>(corrupt[12] ^ 0x5a);
  const std::string corrupt_error = error_of("corrupt.spz", corrupt);
  EXPECT_TRUE(corrupt_error.rfind("not a valid gzip stream", 0) == 0 || corrupt_error.rfind("truncated", 0) == 0 ||
              corrupt_error.rfind("not an SPZ file", 0) == 0)
      << corrupt_error;

  EXPECT_EQ(error_of("v4-streams.spz", version4({s.positions, s.alphas}, 1, 1)),
            "SPZ file has 2 attribute streams, expected 6 (5 without SH)");
  EXPECT_EQ(error_of("v4-no-sh.spz", version4({s.positions, s.alphas, s.colours, s.scales, rotation}, 1, 1)),
            "SPZ file has no SH stream");
  EXPECT_EQ(error_of("v4-size.spz",
                     version4({s.positions, s.alphas, s.colours + "x", s.scales, rotation, s.sh}, 1, 1)),
            "SPZ colours stream holds 4 bytes; 1 splats need 3");
  std::string v4 = version4({s.positions, s.alphas, s.colours, s.scales, rotation, s.sh}, 1, 1);
  EXPECT_EQ(error_of("v4-cut.spz", v4.substr(0, v4.size() - 3)).rfind("truncated file: needs", 0), 0u);
  std::string toc = v4;
  toc[16] = 8;  // table of contents inside the header
  EXPECT_EQ(error_of("v4-toc.spz", toc), "SPZ table of contents at byte 8 overlaps the 32-byte header");
  EXPECT_EQ(error_of("v4-gzip.spz", gzip(header(4, 1, 1, 12) + body)), "SPZ version 4 must not be gzip-compressed");
}

}  // namespace spz_test
}  // namespace
}  // namespace ii
