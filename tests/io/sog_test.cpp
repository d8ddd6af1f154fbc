// SOG: round trips within the format's quantisation (16-bit log positions, 8-bit rotations and
// opacity, 256-entry codebooks, the SH palette), the folder form (meta.json beside its
// images), and bad bundles with their exact messages.
#include <gtest/gtest.h>
#include <zip.h>

#include <cmath>
#include <map>
#include <random>

#include <nlohmann/json.hpp>

#include "io/sog.h"
#include "io/splat_file.h"
#include "io/zip_archive.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

TEST(Sog, RoundTripsWithinItsQuantisation) {
  for (int rest : {0, 3, 15}) {
    const SplatCloud c = test::random_splats(700, rest, 11 + rest, 8.f);
    const fs::path p = test::temp_dir("sog") / fmt::format("round-{}.sog", rest);
    write_splats(p, c);
    const SplatCloud d = read_splats(p);
    const std::vector<size_t> order = morton_order(c.means);  // the order the splats are stored in
    ASSERT_EQ(d.size(), c.size());
    ASSERT_EQ(d.sh_rest_per_channel, rest);
    for (size_t s = 0; s < d.size(); ++s) {
      const size_t i = order[s];
      for (int a = 0; a < 3; ++a) {
        // 16 bits over log(1 + 8) on each side: a step of 2·2.2/65535 in log space.
        const double x = c.means[i * 3 + a];
        ASSERT_NEAR(d.means[s * 3 + a], x, (1 + std::abs(x)) * 2.3 * 2 / 65535 + 1e-5) << s;
        // 256 entries over [-7, -1] and [-1.5, 1.5]: the nearest entry is within half a gap.
        ASSERT_NEAR(d.log_scales[s * 3 + a], c.log_scales[i * 3 + a], 0.03) << s;
        ASSERT_NEAR(d.sh_dc[s * 3 + a], c.sh_dc[i * 3 + a], 0.015) << s;
      }
      const double alpha_c = 1 / (1 + std::exp(-c.opacity_logit[i])), alpha_d = 1 / (1 + std::exp(-d.opacity_logit[s]));
      ASSERT_NEAR(alpha_d, alpha_c, 0.5 / 255 + 1e-6);
      ASSERT_LT(test::rotation_angle(&d.rotations[s * 4], &c.rotations[i * 4]), 0.02) << s;  // 8 bits per component
      // 700 splats, a palette of 700: every set is its own entry, each value within the codebook's half gap.
      for (int k = 0; k < 3 * rest; ++k)
        ASSERT_NEAR(d.sh_rest[s * 3 * rest + k], c.sh_rest[i * 3 * rest + k], 0.01) << s << " " << k;
    }
  }
}

TEST(Sog, ALargePaletteIsFittedNotCopied) {
  // 6000 splats of SH degree 1 drawn around 20 sets: the 4096-entry palette finds them.
  std::mt19937 rng(4);
  std::normal_distribution<float> noise(0, 0.01f);
  SplatCloud c = test::random_splats(6000, 3, 5, 8.f);
  std::vector<float> sets(20 * 9);
  for (float& v : sets) v = std::uniform_real_distribution<float>(-0.8f, 0.8f)(rng);
  for (size_t i = 0; i < c.size(); ++i)
    for (int k = 0; k < 9; ++k) c.sh_rest[i * 9 + k] = sets[(i % 20) * 9 + k] + noise(rng);
  const fs::path p = test::temp_dir("sog") / "palette.sog";
  write_splats(p, c);
  const SplatCloud d = read_splats(p);
  const std::vector<size_t> order = morton_order(c.means);
  double worst = 0;
  for (size_t s = 0; s < d.size(); ++s)
    for (int k = 0; k < 9; ++k) worst = std::max(worst, double(std::abs(d.sh_rest[s * 9 + k] - c.sh_rest[order[s] * 9 + k])));
  EXPECT_LT(worst, 0.06);
}

// The entries of a bundle, to make bad ones from a good one.
std::map<std::string, std::vector<uint8_t>> entries_of(const fs::path& bundle) {
  const ZipArchive zip(bundle);
  std::map<std::string, std::vector<uint8_t>> out;
  for (const std::string& name : zip.names()) out[name] = zip.read(name);
  return out;
}

void write_bundle(const fs::path& p, const std::map<std::string, std::vector<uint8_t>>& entries) {
  int err = 0;
  zip_t* z = zip_open(p.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
  ASSERT_NE(z, nullptr);
  for (const auto& [name, bytes] : entries)
    ASSERT_GE(zip_file_add(z, name.c_str(), zip_source_buffer(z, bytes.data(), bytes.size(), 0), 0), 0);
  ASSERT_EQ(zip_close(z), 0);
}

std::vector<uint8_t> bytes_of(const std::string& s) { return {s.begin(), s.end()}; }

class SogBad : public ::testing::Test {
 protected:
  fs::path dir = test::temp_dir("sog-bad");
  std::map<std::string, std::vector<uint8_t>> good;
  json meta;
  void SetUp() override {
    write_sog(dir / "good.sog", test::random_splats(50, 3, 2, 8.f));
    good = entries_of(dir / "good.sog");
    meta = json::parse(good["meta.json"].begin(), good["meta.json"].end());
  }
  // The error for the good bundle with `change` applied to its entries (a changed meta.json).
  std::string error(const std::string& name, const std::function<void(std::map<std::string, std::vector<uint8_t>>&, json&)>& change) {
    auto entries = good;
    json m = meta;
    change(entries, m);
    if (m != meta) entries["meta.json"] = bytes_of(m.dump());
    write_bundle(dir / name, entries);
    const std::string msg = test::error_message([&] { read_sog(dir / name); });
    const std::string prefix = (dir / name).string() + ": ";
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;
    return msg.substr(std::min(msg.size(), prefix.size()));
  }
};

TEST_F(SogBad, EachProblemHasItsMessage) {
  test::write_bytes(dir / "text.sog", "hello");
  EXPECT_EQ(test::error_message([&] { read_sog(dir / "text.sog"); }).rfind((dir / "text.sog").string() + ": not a readable zip archive", 0), 0u);
  EXPECT_EQ(error("no-meta.sog", [](auto& e, json&) { e.erase("meta.json"); }), "SOG bundle has no meta.json");
  EXPECT_EQ(error("bad-json.sog", [](auto& e, json&) { e["meta.json"] = bytes_of("{\"version\": 2,"); }).rfind("SOG meta.json is not valid JSON", 0), 0u);
  EXPECT_EQ(error("v1.sog", [](auto&, json& m) { m.erase("version"); }),
            "SOG version 1 (no version in meta.json) is not supported: convert it with splat-transform");
  EXPECT_EQ(error("v3.sog", [](auto&, json& m) { m["version"] = 3; }), "SOG version 3 is not supported (2)");
  EXPECT_EQ(error("count.sog", [](auto&, json& m) { m["count"] = -1; }), "SOG splat count -1 is not a count of at most 16777216");
  EXPECT_EQ(error("no-means.sog", [](auto&, json& m) { m.erase("means"); }), "SOG meta.json has no means");
  EXPECT_EQ(error("mins.sog", [](auto&, json& m) { m["means"]["mins"] = json::array({1, 2}); }), "SOG meta.json means.mins must be 3 numbers");
  EXPECT_EQ(error("book.sog", [](auto&, json& m) { m["scales"]["codebook"] = json::array({1, 2, 3}); }),
            "SOG meta.json scales.codebook must be 256 numbers");
  EXPECT_EQ(error("files.sog", [](auto&, json& m) { m["quats"]["files"] = json::array(); }),
            "SOG meta.json quats.files must name 1 file");
  EXPECT_EQ(error("path.sog", [](auto&, json& m) { m["quats"]["files"] = json::array({"../quats.webp"}); }),
            "SOG file name '../quats.webp' is not a plain file name");
  EXPECT_EQ(error("missing.sog", [](auto& e, json&) { e.erase("quats.webp"); }), "SOG bundle has no quats.webp");
  EXPECT_EQ(error("not-webp.sog", [](auto& e, json&) { e["quats.webp"] = bytes_of("RIFF1234WEBPxxxx"); }),
            "SOG image quats.webp is not a WebP image");
  EXPECT_EQ(error("small.sog", [](auto&, json& m) { m["count"] = 100000; }),
            "SOG image means_l.webp has 8x8 texels for 100000 splats");
  EXPECT_EQ(error("bands.sog", [](auto&, json& m) { m["shN"]["bands"] = 4; }), "SOG shN.bands 4 is not 1, 2 or 3");
  EXPECT_EQ(error("palette.sog", [](auto&, json& m) { m["shN"]["count"] = 10; }),
            "SOG splat 0 has SH label 42, beyond the palette of 10");
  EXPECT_EQ(error("shape.sog", [](auto&, json& m) { m["shN"]["bands"] = 2; }),
            "SOG image shN_centroids.webp is 192x1: 50 palette entries of 8 coefficients need 512 columns and 1 rows");
}

TEST(Sog, TheFolderFormReadsLikeTheBundle) {
  const fs::path dir = test::temp_dir("sog-folder");
  write_sog(dir / "x.sog", test::random_splats(30, 0, 3, 8.f));
  for (const auto& [name, bytes] : entries_of(dir / "x.sog"))
    test::write_bytes(dir / name, std::string(bytes.begin(), bytes.end()));
  const SplatCloud a = read_splats(dir / "x.sog"), b = read_splats(dir / "meta.json");
  EXPECT_EQ(a.means, b.means);
  EXPECT_EQ(a.rotations, b.rotations);
}

}  // namespace
}  // namespace ii
