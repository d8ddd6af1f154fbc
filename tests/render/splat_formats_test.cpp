// Splat formats against the reference implementations and by their renders: PlayCanvas's
// splat-transform (web/node_modules, npm; it writes compressed PLY and SOG as SuperSplat does
// and SPZ with Niantic's library) converts a real capture to each format, and our files back
// to PLY. Its files must read here, ours there, and every decoded cloud must render like the
// float original (PSNR from a turntable of cameras around the splats).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "camera/trajectory.h"
#include "common/process.h"
#include "eval/metrics.h"
#include "gaussians/gaussians.h"
#include "io/splat_file.h"
#include "render/rasterizer.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

const fs::path kSplatTransform = "web/node_modules/@playcanvas/splat-transform/bin/cli.mjs";

// splat-transform IN OUT (extra options first); the test fails with its log otherwise.
void splat_transform(const fs::path& in, const fs::path& out, const std::vector<std::string>& options = {}) {
  std::vector<std::string> args = {kSplatTransform.string(), "-q", "-w"};
  args.insert(args.end(), options.begin(), options.end());
  args.push_back(in.string());
  args.push_back(out.string());
  const fs::path log = out.string() + ".log";
  try {
    run_logged(find_executable("node"), args, log, "splat-transform");
  } catch (const Error& e) {
    FAIL() << e.what() << "\n" << test::file_bytes(log);
  }
}

// The guitar capture with view-dependent colour added (degree 3, seeded), as a float PLY.
SplatCloud source_cloud(const fs::path& dir) {
  SplatCloud c = read_splats(test::shared_path("data/splats/guitar.compressed.ply"));
  c.sh_rest_per_channel = 15;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  c.sh_rest.resize(c.size() * 45);
  for (float& v : c.sh_rest) v = u(rng);
  write_splats(dir / "source.ply", c);
  return read_splats(dir / "source.ply");
}

// The first `n` splats.
SplatCloud first(const SplatCloud& c, size_t n) {
  SplatCloud f = c;
  const size_t k = static_cast<size_t>(c.sh_rest_per_channel) * 3;
  f.means.resize(n * 3);
  if (!f.normals.empty()) f.normals.resize(n * 3);
  f.sh_dc.resize(n * 3);
  f.sh_rest.resize(n * k);
  f.opacity_logit.resize(n);
  f.log_scales.resize(n * 3);
  f.rotations.resize(n * 4);
  return f;
}

// Mean PSNR of `b`'s renders against `a`'s from a turntable of 6 cameras, 256².
double render_psnr(const SplatCloud& a, const SplatCloud& b) {
  const GaussianSet ga = gaussians_from_splats(a), gb = gaussians_from_splats(b);
  const BoundingSphere bounds = visible_bounds(ga);
  double sum = 0;
  const std::vector<Camera> cameras =
      turntable_around_sphere(bounds.centre, bounds.radius, 50 * M_PI / 180, 20, -Eigen::Vector3d::UnitY(), 6, 256, 256);
  for (const Camera& c : cameras) {
    RenderCamera rc;
    rc.camera = c;
    const torch::Tensor ra = render(ga, rc).rgb.permute({2, 0, 1}).unsqueeze(0);
    const torch::Tensor rb = render(gb, rc).rgb.permute({2, 0, 1}).unsqueeze(0);
    sum += psnr(ra, rb).item<double>();
  }
  return sum / static_cast<double>(cameras.size());
}

class SplatFormats : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(kSplatTransform)) GTEST_SKIP() << "not installed: " << kSplatTransform << " (make deps)";
    if (find_executable("node").empty()) GTEST_SKIP() << "node is not installed (make deps)";
    if (const std::string why = test::shared_missing("data/splats/guitar.compressed.ply"); !why.empty()) GTEST_SKIP() << why;
  }
  fs::path dir = test::temp_dir("splat-formats");
};

TEST_F(SplatFormats, TheirFilesReadHereAndRenderLikeTheOriginal) {
  const SplatCloud source = source_cloud(dir);
  // splat-transform fits SOG's SH palette (64 Ki entries here) with k-means in JavaScript when
  // there is no GPU: minutes for the whole capture, so its SOG is made from the first 3000 splats.
  const SplatCloud small = first(source, 3000);
  write_splats(dir / "source-small.ply", small);
  struct Case {
    std::string file;
    std::vector<std::string> options;
    double min_psnr;
    bool small = false;
  };
  for (const Case& c : std::vector<Case>{{"theirs-v3.spz", {"--spz-version", "3"}, 40},
                                         {"theirs-v4.spz", {"--spz-version", "4"}, 40},
                                         {"theirs.compressed.ply", {}, 40},
                                         {"theirs.sog", {"-g", "cpu"}, 30, true}}) {
    const SplatCloud& original = c.small ? small : source;
    splat_transform(dir / (c.small ? "source-small.ply" : "source.ply"), dir / c.file, c.options);
    const SplatCloud theirs = read_splats(dir / c.file);
    ASSERT_EQ(theirs.size(), original.size()) << c.file;
    EXPECT_EQ(theirs.sh_rest_per_channel, 15) << c.file;
    const double p = render_psnr(original, theirs);
    EXPECT_GE(p, c.min_psnr) << c.file;
    std::printf("%s: %.2f dB against the float original\n", c.file.c_str(), p);
  }
}

TEST_F(SplatFormats, OurFilesReadThereAsWeReadThem) {
  const SplatCloud source = source_cloud(dir);
  for (const std::string file : {"ours.spz", "ours.compressed.ply", "ours.sog"}) {
    write_splats(dir / file, source);
    const SplatCloud ours = read_splats(dir / file);
    const double p = render_psnr(source, ours);
    EXPECT_GE(p, file == "ours.sog" ? 30 : 40) << file;
    std::printf("%s: %.2f dB against the float original\n", file.c_str(), p);
    // Their decoder, to a float PLY: the same splats in the same order, up to float rounding.
    splat_transform(dir / file, dir / (file + ".back.ply"));
    const SplatCloud back = read_splats(dir / (file + ".back.ply"));
    ASSERT_EQ(back.size(), ours.size()) << file;
    ASSERT_EQ(back.sh_rest_per_channel, ours.sh_rest_per_channel) << file;
    auto near = [&](const std::vector<float>& a, const std::vector<float>& b, double tolerance, const char* what) {
      ASSERT_EQ(a.size(), b.size());
      for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_NEAR(a[i], b[i], tolerance * std::max(1.0, std::abs(static_cast<double>(a[i])))) << file << " " << what << " " << i;
      }
    };
    near(back.means, ours.means, 1e-5, "means");
    near(back.log_scales, ours.log_scales, 1e-5, "log scales");
    near(back.sh_dc, ours.sh_dc, 1e-5, "colours");
    // Opacities as opacities: a byte of 255 decodes to a logit of 40 here, 13.8 there (both 1).
    std::vector<float> back_alpha, our_alpha;
    for (float l : back.opacity_logit) back_alpha.push_back(1 / (1 + std::exp(-l)));
    for (float l : ours.opacity_logit) our_alpha.push_back(1 / (1 + std::exp(-l)));
    near(back_alpha, our_alpha, 1e-5, "opacities");
    near(back.sh_rest, ours.sh_rest, 1e-5, "SH");
    for (size_t i = 0; i < ours.size(); ++i) {
      double dot = 0;
      for (int k = 0; k < 4; ++k) dot += double(back.rotations[i * 4 + k]) * ours.rotations[i * 4 + k];
      ASSERT_NEAR(std::abs(dot), 1.0, 1e-5) << file << " rotation " << i;
    }
  }
}

}  // namespace
}  // namespace ii
