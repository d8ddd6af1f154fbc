// Refinement on a tiny scene rendered from known Gaussians: it lowers the loss, ignores masked
// pixels entirely, repeats exactly for a seed, and drops what became transparent.
#include <gtest/gtest.h>

#include <algorithm>

#include <nlohmann/json.hpp>

#include "io/ply.h"
#include "refine/refine.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"
#include "test_support.h"

namespace ii {
namespace {

// A 6 x 6 grid of Gaussians on the plane z = -3, in front of cameras at the origin.
GaussianSet grid(float colour_shift = 0) {
  std::vector<float> means, colours;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) {
      means.insert(means.end(), {-1.f + 0.4f * i, -0.8f + 0.32f * j, -3.f});
      colours.insert(colours.end(), {0.2f + 0.12f * i + colour_shift, 0.8f - 0.1f * j, 0.5f});
    }
  GaussianSet g;
  g.means = torch::tensor(means).reshape({-1, 3});
  g.colors = torch::tensor(colours).reshape({-1, 3});
  g.scales = torch::full({36, 3}, 0.18f);
  g.quats = torch::tensor({1.f, 0.f, 0.f, 0.f}).repeat({36, 1});
  g.opacities = torch::full({36}, 0.9f);
  return g;
}

std::vector<RefineView> views_of(const GaussianSet& truth) {
  std::vector<RefineView> views;
  for (int k = 0; k < 3; ++k) {
    RefineView v;
    v.name = "v" + std::to_string(k);
    v.camera.K = Intrinsics::from_fov(32, 24, 0.9, 0.7);
    v.camera.c2w(0, 3) = 0.3 * (k - 1);
    RenderCamera rc;
    rc.camera = v.camera;
    v.rgb = image_from_hwc(render(truth, rc).rgb);
    views.push_back(std::move(v));
  }
  return views;
}

RefineOptions few_steps(int steps) {
  RefineOptions o;
  o.steps = steps;
  o.colour_lr = 0.02;
  o.seed = 3;
  return o;
}

TEST(Refine, LowersTheLoss) {
  const RefineResult r = refine_gaussians(grid(0.25f), views_of(grid()), few_steps(30));
  ASSERT_EQ(r.losses.size(), 30u);
  EXPECT_LT(r.losses.back(), 0.5 * r.losses.front());
  EXPECT_EQ(r.dropped, 0);
  EXPECT_EQ(r.gaussians.size(), 36);
}

TEST(Refine, MaskedPixelsHaveNoInfluence) {
  std::vector<RefineView> views = views_of(grid());
  for (size_t k = 1; k < views.size(); ++k) {
    Image mask(32, 24, 1);
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 14; ++x) mask.at(y, x) = 1;
    views[k].mask = mask;
  }
  const RefineResult a = refine_gaussians(grid(0.25f), views, few_steps(6));
  for (size_t k = 1; k < views.size(); ++k)
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 14; ++x) views[k].rgb.at(y, x, 1) = 0.f;  // paint the masked part
  const RefineResult b = refine_gaussians(grid(0.25f), views, few_steps(6));
  EXPECT_TRUE(torch::equal(a.gaussians.colors, b.gaussians.colors));
  EXPECT_TRUE(torch::equal(a.gaussians.means, b.gaussians.means));
}

TEST(Refine, SameSeedSameGaussians) {
  const RefineResult a = refine_gaussians(grid(0.25f), views_of(grid()), few_steps(5));
  const RefineResult b = refine_gaussians(grid(0.25f), views_of(grid()), few_steps(5));
  EXPECT_TRUE(torch::equal(a.gaussians.means, b.gaussians.means));
  EXPECT_TRUE(torch::equal(a.gaussians.scales, b.gaussians.scales));
  EXPECT_EQ(a.losses, b.losses);
}

TEST(Refine, TransparentGaussiansAreDropped) {
  GaussianSet start = grid();
  start.opacities[0] = 1e-4f;
  const RefineResult r = refine_gaussians(start, views_of(grid()), few_steps(0));
  EXPECT_EQ(r.dropped, 1);
  EXPECT_EQ(r.gaussians.size(), 35);
}

TEST(Refine, ShDegreeStartsFromTheColoursAndFitsViewDependence) {
  RefineOptions o = few_steps(0);
  o.sh_degree = 2;
  const RefineResult start = refine_gaussians(grid(0.25f), views_of(grid()), o);
  ASSERT_EQ(start.gaussians.sh_degree, 2);
  ASSERT_EQ(start.gaussians.colors.sizes(), (std::vector<int64_t>{36, 9, 3}));
  EXPECT_TRUE(torch::allclose(rgb_from_sh_dc(start.gaussians.colors.select(1, 0)), grid(0.25f).colors, 1e-5, 1e-6));
  EXPECT_EQ(start.gaussians.colors.narrow(1, 1, 8).abs().max().item<float>(), 0.f);

  o.steps = 30;
  const RefineResult r = refine_gaussians(grid(0.25f), views_of(grid()), o);
  EXPECT_LT(r.losses.back(), 0.5 * r.losses.front());
  EXPECT_GT(r.gaussians.colors.narrow(1, 1, 8).abs().max().item<float>(), 0.f);
}

TEST(Refine, BadInputsAreClearErrors) {
  EXPECT_EQ(test::error_message([] { refine_gaussians(grid(), {}, few_steps(1)); }), "refine: no views to refine against");
  std::vector<RefineView> views = views_of(grid());
  views[1].mask = Image(5, 5, 1);
  EXPECT_EQ(test::error_message([&] { refine_gaussians(grid(), views, few_steps(1)); }),
            "refine: the mask of view v1 does not fit its 32x24 image");
  RefineOptions o = few_steps(1);
  o.sh_degree = 4;
  EXPECT_EQ(test::error_message([&] { refine_gaussians(grid(), views_of(grid()), o); }),
            "refine: the SH degree must be 0 to 3, got 4");
}

TEST(RefineCli, InferRefinesAgainstEveryViewNotHeldOut) {
  II_REQUIRE_CLI(exe);
  II_REQUIRE_SHARED(dir, "data/statue");
  const std::filesystem::path tmp = test::temp_dir("refine-cli");
  const std::filesystem::path log = tmp / "log.txt";
  ASSERT_EQ(test::run_command(exe.string() + " infer --scene '" + dir.string() +
                                  "' --height 64 --hold-out-every 8 --refine 2 --refine-sh-degree 1 "
                                  "--keep-unrefined --threads 2 --out '" +
                                  tmp.string() + "'",
                              log),
            0)
      << test::file_bytes(log);
  const nlohmann::json run = nlohmann::json::parse(test::file_bytes(tmp / "run.json"));
  EXPECT_EQ(run["refine"]["steps"], 2);
  const nlohmann::json& views = run["refine"]["views"];
  EXPECT_EQ(views.size(), 25u);  // every input view of the scene but 0, 8, 16, 24
  for (const char* held_out : {"IMG_2707", "IMG_2715", "IMG_2723", "IMG_2731"})
    EXPECT_EQ(std::find(views.begin(), views.end(), held_out), views.end()) << held_out;
  EXPECT_EQ(views[0], run["context"][0]);  // the reference first
  EXPECT_EQ(run["refine"]["losses"].size(), 2u);
  EXPECT_EQ(run["refine"]["sh_degree"], 1);
  EXPECT_EQ(read_splat_ply(tmp / "gaussians.ply").sh_rest_per_channel, 3);
  EXPECT_EQ(read_splat_ply(tmp / "gaussians-unrefined.ply").sh_rest_per_channel, 0);
  EXPECT_NE(test::file_bytes(log).find("refine 2/2"), std::string::npos) << test::file_bytes(log);
}

TEST(RefineCli, EvalRefinesBeforeRendering) {
  II_REQUIRE_CLI(exe);
  const std::filesystem::path tmp = test::temp_dir("refine-eval");
  const std::filesystem::path log = tmp / "log.txt";
  ASSERT_EQ(test::run_command(exe.string() + " synth --out '" + (tmp / "rooms").string() +
                                  "' --views 4 --test-views 2 --width 48 --height 40 --object procedural",
                              log),
            0)
      << test::file_bytes(log);
  const std::string scene = (tmp / "rooms" / "scene_000").string();
  ASSERT_EQ(test::run_command(exe.string() + " eval --scene '" + scene + "' --height 40 --refine 3 --out '" +
                                  (tmp / "eval").string() + "'",
                              log),
            0)
      << test::file_bytes(log);
  const nlohmann::json m = nlohmann::json::parse(test::file_bytes(tmp / "eval" / "metrics.json"));
  EXPECT_EQ(m["prediction"]["after_prediction"]["refine"]["steps"], 3);
  // A scene with no views besides the context: the reference and the other context views.
  EXPECT_EQ(m["prediction"]["after_prediction"]["refine"]["views"].size(), 4u);
  EXPECT_EQ(test::run_command(exe.string() + " eval --scene '" + scene + "' --method telea --refine 3 --out x", log), 1);
  EXPECT_NE(test::file_bytes(log).find("error: --refine refines the network's prediction"), std::string::npos)
      << test::file_bytes(log);
}

}  // namespace
}  // namespace ii
