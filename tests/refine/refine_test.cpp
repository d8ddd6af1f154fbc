// Refinement on a tiny scene rendered from known Gaussians: it lowers the loss, ignores masked
// pixels entirely, repeats exactly for a seed, and drops what became transparent.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "io/image.h"
#include "io/ply.h"
#include "refine/adam.h"
#include "refine/densify.h"
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

// `n` views of `truth` side by side (v0 ... v<n-1>), from cameras 0.15 apart.
std::vector<RefineView> views_across(const GaussianSet& truth, int n) {
  std::vector<RefineView> views;
  for (int k = 0; k < n; ++k) {
    RefineView v;
    v.name = "v" + std::to_string(k);
    v.camera.K = Intrinsics::from_fov(32, 24, 0.9, 0.7);
    v.camera.c2w(0, 3) = 0.15 * (k - (n - 1) / 2.0);
    RenderCamera rc;
    rc.camera = v.camera;
    v.rgb = image_from_hwc(render(truth, rc).rgb);
    views.push_back(std::move(v));
  }
  return views;
}

// The plain optimisation: no new Gaussians, no colour maps, full resolution.
RefineOptions few_steps(int steps) {
  RefineOptions o;
  o.steps = steps;
  o.colour_lr = 0.02;
  o.seed = 3;
  o.cover = false;
  o.densify.enabled = false;
  o.exposure = false;
  o.coarse_to_fine = false;
  o.opacity_resets.clear();
  return o;
}

// Everything switched on, densifying every 4 steps from step 2 on.
RefineOptions all_parts(int steps) {
  RefineOptions o = few_steps(steps);
  o.cover = o.densify.enabled = o.exposure = o.coarse_to_fine = true;
  o.densify_every = 4;
  o.densify.grad_threshold = 0.015;  // these tiny views give large gradients: a few qualify
  o.opacity_resets = {0.3};
  o.opacity_lr = 0.25;  // the opacities come back from the reset within ~20 steps
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
  for (const RefineOptions& o : {few_steps(6), all_parts(40)}) {
    std::vector<RefineView> painted = views;
    for (size_t k = 1; k < views.size(); ++k)
      for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 14; ++x) painted[k].rgb.at(y, x, 1) = 0.f;  // paint the masked part
    const RefineResult a = refine_gaussians(grid(0.25f), views, o);
    const RefineResult b = refine_gaussians(grid(0.25f), painted, o);
    ASSERT_EQ(a.gaussians.size(), b.gaussians.size());
    EXPECT_TRUE(torch::equal(a.gaussians.colors, b.gaussians.colors));
    EXPECT_TRUE(torch::equal(a.gaussians.means, b.gaussians.means));
    EXPECT_EQ(a.losses, b.losses);
  }
}

// Inside a view's mask its `in_mask` picture is fitted as if the photo showed it there (as
// refine_prediction fits the start's render in the other views' masks); a held-out view still
// scores its own pixels alone.
TEST(Refine, AViewFitsItsInMaskPictureInsideItsMask) {
  auto left_half = [] {
    Image mask(32, 24, 1);
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 14; ++x) mask.at(y, x) = 1;
    return mask;
  };
  std::vector<RefineView> masked = views_of(grid()), whole = views_of(grid());
  const std::vector<RefineView> other = views_of(grid(0.25f));  // what to fit inside the masks
  for (size_t k = 1; k < masked.size(); ++k) {
    masked[k].mask = left_half();
    masked[k].in_mask = other[k].rgb;
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 14; ++x)
        for (int c = 0; c < 3; ++c) whole[k].rgb.at(y, x, c) = other[k].rgb.at(y, x, c);
  }
  const RefineResult a = refine_gaussians(grid(0.25f), masked, few_steps(6));
  const RefineResult b = refine_gaussians(grid(0.25f), whole, few_steps(6));
  EXPECT_EQ(a.losses, b.losses);
  EXPECT_TRUE(torch::equal(a.gaussians.means, b.gaussians.means));
  EXPECT_TRUE(torch::equal(a.gaussians.colors, b.gaussians.colors));

  RefineOptions o = few_steps(10);
  o.hold_out_every = 2;  // v2, v4 and v6 score
  std::vector<RefineView> held = views_across(grid(), 7);
  for (RefineView& v : held) v.mask = left_half();
  std::vector<RefineView> held_painted = held;
  for (int k : {2, 4, 6}) held_painted[static_cast<size_t>(k)].in_mask = other[1].rgb;
  const RefineResult c = refine_gaussians(grid(0.25f), held, o);
  const RefineResult d = refine_gaussians(grid(0.25f), held_painted, o);
  EXPECT_EQ(c.held_out, (std::vector<std::string>{"v2", "v4", "v6"}));
  EXPECT_EQ(c.start_psnr, d.start_psnr);
  EXPECT_EQ(c.iterates, d.iterates);
  Image wrong(31, 24, 3);
  masked[1].in_mask = wrong;
  EXPECT_EQ(test::error_message([&] { refine_gaussians(grid(0.25f), masked, few_steps(1)); }),
            "refine: what view v1 fits inside its mask does not fit its 32x24 image");
}

TEST(Refine, SameSeedSameGaussians) {
  const RefineResult a = refine_gaussians(grid(0.25f), views_of(grid()), all_parts(30));
  const RefineResult b = refine_gaussians(grid(0.25f), views_of(grid()), all_parts(30));
  EXPECT_GT(a.cloned + a.split, 0);  // the run densified
  ASSERT_EQ(a.gaussians.size(), b.gaussians.size());
  EXPECT_TRUE(torch::equal(a.gaussians.means, b.gaussians.means));
  EXPECT_TRUE(torch::equal(a.gaussians.scales, b.gaussians.scales));
  EXPECT_EQ(a.losses, b.losses);
  RefineOptions other = all_parts(30);
  other.seed = 4;
  EXPECT_NE(refine_gaussians(grid(0.25f), views_of(grid()), other).losses, a.losses);
}

TEST(Refine, AllPartsLowerTheLossAndReportTheColourMaps) {
  const RefineResult r = refine_gaussians(grid(0.25f), views_of(grid()), all_parts(80));
  // The first steps are at a coarser resolution: compared with the loss at full resolution.
  const double start = refine_gaussians(grid(0.25f), views_of(grid()), few_steps(1)).losses[0];
  EXPECT_LT(r.losses.back(), 0.5 * start);
  ASSERT_EQ(r.exposure.size(), 3u);
  EXPECT_EQ(r.exposure[0].first, "v0");
  EXPECT_EQ(r.exposure[0].second, (std::array<double, 6>{1, 1, 1, 0, 0, 0}));  // the reference as it is
  EXPECT_NE(r.exposure[1].second, r.exposure[0].second);
  EXPECT_EQ(r.steps, 80);
}

// The grid's right half only: the views' left parts are not covered.
TEST(Refine, UncoveredPixelsGetGaussiansWhereTheViewSawSomething) {
  const GaussianSet truth = grid();
  const torch::Tensor right = truth.means.select(1, 0) > 0;
  GaussianSet half;
  for (auto [to, from] : {std::pair{&half.means, &truth.means}, {&half.scales, &truth.scales},
                          {&half.quats, &truth.quats}, {&half.opacities, &truth.opacities},
                          {&half.colors, &truth.colors}})
    *to = from->index({right});
  RefineOptions o = few_steps(1);
  o.cover = true;
  const RefineResult r = refine_gaussians(half, views_of(truth), o);
  ASSERT_GT(r.covered, 0);
  EXPECT_EQ(r.gaussians.size(), half.size() + r.covered);
  // The new ones fill the left side, at the depth of what the views see (z = -3).
  const torch::Tensor added = r.gaussians.means.narrow(0, half.size(), r.covered);
  EXPECT_LT(added.select(1, 0).mean().item<double>(), 0);
  EXPECT_NEAR(added.select(1, 2).mean().item<double>(), -3, 0.05);
}

TEST(Densify, LargeGradientsCloneSmallAndSplitLargeGaussiansTransparentOnesGo) {
  // extent 10: scales up to 0.1 are small.
  const torch::Tensor grad = torch::tensor({3e-4, 1e-4, 5e-4, 2e-4, 9e-4});
  const torch::Tensor scale = torch::tensor({0.05, 0.05, 0.5, 0.1, 0.05});
  const torch::Tensor opacity = torch::tensor({0.5, 0.5, 0.5, 0.5, 0.001});
  const DensifyDecision d = decide_densification(grad, scale, opacity, 10, 100, DensifyOptions{});
  auto list = [](const torch::Tensor& b) {
    std::vector<int64_t> v;
    for (int64_t i = 0; i < b.size(0); ++i)
      if (b[i].item<bool>()) v.push_back(i);
    return v;
  };
  EXPECT_EQ(list(d.clone), (std::vector<int64_t>{0, 3}));  // 2e-4 is at the threshold
  EXPECT_EQ(list(d.split), (std::vector<int64_t>{2}));
  EXPECT_EQ(list(d.prune), (std::vector<int64_t>{4}));  // pruned even with the largest gradient
  EXPECT_EQ(d.added(), 3);
  // A cap of 5 with one pruned leaves room for one more: the largest gradient (Gaussian 2).
  const DensifyDecision capped = decide_densification(grad, scale, opacity, 10, 5, DensifyOptions{});
  EXPECT_EQ(list(capped.clone), std::vector<int64_t>{});
  EXPECT_EQ(list(capped.split), (std::vector<int64_t>{2}));
  EXPECT_EQ(capped.added(), 1);
}

TEST(Densify, SplitChildrenSitAlongTheLongestAxis) {
  // Rotated 90 degrees about z: the local y axis (the longest) points along -x in the world.
  const double h = std::sqrt(0.5);
  const torch::Tensor quats = torch::tensor({h, 0.0, 0.0, h}).reshape({1, 4}).to(torch::kFloat32);
  const torch::Tensor means = torch::tensor({1.f, 2.f, 3.f}).reshape({1, 3});
  const torch::Tensor scales = torch::tensor({0.1f, 0.3f, 0.2f}).reshape({1, 3});
  const auto [a, b] = split_centres(means, scales, quats);
  const double d = 0.3 * std::sqrt(1 - 1 / (1.6 * 1.6));
  EXPECT_TRUE(torch::allclose(a, torch::tensor({1 - d, 2.0, 3.0}).reshape({1, 3}).to(torch::kFloat32), 1e-5, 1e-6))
      << a;
  EXPECT_TRUE(torch::allclose(b, torch::tensor({1 + d, 2.0, 3.0}).reshape({1, 3}).to(torch::kFloat32), 1e-5, 1e-6))
      << b;
}

TEST(RowAdam, AnAppendedRowStepsLikeAFreshAdam) {
  // Adam's first step is the rate times the gradient's sign, whatever the gradient's size; a
  // row appended after 200 steps must take that same first step (with the optimiser's own
  // step count it would take 1.35 times the rate here, 3.16 times after thousands of steps).
  torch::Tensor x = torch::zeros({1, 2}).requires_grad_(true);
  RowAdam adam;
  adam.add(&x, 0.01);
  for (int i = 0; i < 200; ++i) {
    x.mutable_grad() = torch::ones({1, 2});
    adam.step();
  }
  adam.append_rows({torch::tensor({{5.f, 5.f}})});
  ASSERT_EQ(x.size(0), 2);
  x.mutable_grad() = torch::tensor({{1.f, 1.f}, {-40.f, 0.003f}});
  adam.step();
  EXPECT_NEAR(x[1][0].item<double>(), 5 + 0.01, 1e-6);
  EXPECT_NEAR(x[1][1].item<double>(), 5 - 0.01, 1e-6);
  // Rows kept after a removal keep their own count: the appended row's second step is still
  // the rate (the same gradient twice: m / sqrt(v) = 1 after correction).
  adam.keep_rows(torch::tensor({false, true}));
  ASSERT_EQ(x.size(0), 1);
  x.mutable_grad() = torch::tensor({{-40.f, 0.003f}});
  adam.step();
  EXPECT_NEAR(x[0][0].item<double>(), 5 + 0.02, 1e-6);
  EXPECT_NEAR(x[0][1].item<double>(), 5 - 0.02, 1e-6);
  // After a restart (3DGS's opacity reset) the next step is again a fresh Adam's first.
  for (int i = 0; i < 50; ++i) {
    x.mutable_grad() = torch::tensor({{1.f, 1.f}});
    adam.step();
  }
  const torch::Tensor before = x.detach().clone();
  adam.restart(0);
  x.mutable_grad() = torch::tensor({{-3.f, 0.5f}});
  adam.step();
  EXPECT_NEAR((x - before)[0][0].item<double>(), 0.01, 1e-6);
  EXPECT_NEAR((x - before)[0][1].item<double>(), -0.01, 1e-6);
}

TEST(Refine, DensifyingAddsGaussiansAndPruningRemovesTransparentOnes) {
  GaussianSet start = grid(0.25f);
  start.opacities[5] = 0.0045f;  // above 1/255 (kept by the final drop), below 0.005 (pruned)
  start.opacities[7] = 0.0045f;
  RefineOptions o = few_steps(8);
  o.densify.enabled = true;
  o.densify_every = 2;
  o.densify.grad_threshold = 0;  // every Gaussian seen qualifies: the cap decides
  o.densify.max_gaussians = 40;
  o.opacity_lr = 0;  // the two stay transparent
  const RefineResult r = refine_gaussians(start, views_of(grid()), o);
  EXPECT_EQ(r.pruned, 2);
  EXPECT_EQ(r.cloned + r.split, 40 - 34);  // up to the cap once the two are gone
  EXPECT_EQ(r.gaussians.size(), 40);
}

// A run continued from a checkpoint (reconstruct --resume) continues its schedule: the resets
// before its start were done before it; one still ahead comes; its step count goes on from there.
TEST(Refine, ARunContinuedPastAResetDoesNotResetAgain) {
  RefineOptions o = few_steps(60);
  o.densify.enabled = true;
  o.densify.grad_threshold = 1e9;
  o.opacity_resets = {0.25, 0.75};
  o.opacity_lr = 0;
  o.first_step = 30;
  const RefineResult r = refine_gaussians(grid(0.25f), views_of(grid()), o);
  EXPECT_EQ(r.steps, 60);
  EXPECT_EQ(r.losses.size(), 30u);
  EXPECT_EQ(r.opacity_resets, 1);  // 0.75 alone
}

TEST(Refine, AnOpacityResetLowersEveryOpacityAndTheViewsBringThemBack) {
  RefineOptions o = few_steps(60);
  o.densify.enabled = true;
  o.densify.grad_threshold = 1e9;  // no clones or splits: the reset alone
  o.opacity_resets = {0.25};       // after step 15 (of 0-59)
  o.opacity_lr = 0;
  const RefineResult frozen = refine_gaussians(grid(0.25f), views_of(grid()), o);
  EXPECT_EQ(frozen.opacity_resets, 1);
  ASSERT_EQ(frozen.gaussians.size(), 36);
  EXPECT_TRUE(torch::allclose(frozen.gaussians.opacities, torch::full({36}, 0.01f), 0, 1e-6)) << frozen.gaussians.opacities;

  // Mean loss over a pass of the three views: the image fades at the reset and comes back.
  o.opacity_lr = 0.25;
  const RefineResult r = refine_gaussians(grid(0.25f), views_of(grid()), o);
  auto pass = [&](size_t first) { return (r.losses[first] + r.losses[first + 1] + r.losses[first + 2]) / 3; };
  EXPECT_GT(pass(16), 3 * pass(13));
  EXPECT_LT(pass(57), 0.3 * pass(16));
  EXPECT_GT(r.gaussians.opacities.mean().item<double>(), 0.3);

  o.opacity_resets.clear();
  EXPECT_EQ(refine_gaussians(grid(0.25f), views_of(grid()), o).opacity_resets, 0);
}

TEST(Refine, ATimeBudgetIsKept) {
  RefineOptions o = all_parts(0);
  o.time_budget_s = 1.5;
  const RefineResult r = refine_gaussians(grid(0.25f), views_of(grid()), o);
  EXPECT_GE(r.seconds, 1.5);
  EXPECT_LE(r.seconds, 1.65);
  EXPECT_GT(r.steps, 5);
}

TEST(Refine, SettingsByNameTimeOrSteps) {
  EXPECT_EQ(refine_setting("fast").time_budget_s, 60);
  EXPECT_EQ(refine_setting("balanced").time_budget_s, 540);
  EXPECT_EQ(refine_setting("best").time_budget_s, 1200);
  EXPECT_EQ(refine_setting("90s").time_budget_s, 90);
  EXPECT_EQ(refine_setting("1.5m").time_budget_s, 90);
  EXPECT_EQ(refine_setting("300").steps, 300);
  EXPECT_EQ(refine_setting("300").time_budget_s, 0);
  EXPECT_FALSE(refine_requested(refine_setting("0")));
  EXPECT_EQ(refine_length(refine_setting("balanced")), "9 minutes");
  EXPECT_EQ(refine_length(refine_setting("1")), "1 step");
  for (const char* bad : {"", "quick", "-5", "5h", "0s", "1e9", "2m30", "1234567"})
    EXPECT_EQ(test::error_message([&] { refine_setting(bad); }),
              fmt::format("refine: '{}' is not a refinement: use fast, balanced or best, a time such as 90s or 2m (up "
                          "to 24 hours), or a number of steps",
                          bad))
        << bad;
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

// Every second view after the first is held out (v2, v4, v6 of seven) and scores the start and
// the iterates; the best of them is the result.
TEST(Refine, HeldOutViewsChooseTheResultAndAnIterateThatBeatsTheStartWins) {
  RefineOptions o = few_steps(30);
  o.hold_out_every = 2;
  o.score_at = {0.5};
  const RefineResult r = refine_gaussians(grid(0.25f), views_across(grid(), 7), o);
  EXPECT_EQ(r.views, (std::vector<std::string>{"v0", "v1", "v3", "v5"}));
  EXPECT_EQ(r.held_out, (std::vector<std::string>{"v2", "v4", "v6"}));
  ASSERT_EQ(r.iterates.size(), 2u);  // at half the run and at its end
  EXPECT_EQ(r.iterates[0].first, 15);
  EXPECT_EQ(r.iterates[1].first, 30);
  EXPECT_GT(r.iterates[1].second, r.start_psnr + 3);
  EXPECT_FALSE(r.kept_start);
  EXPECT_EQ(r.chosen_step, 30);
  const nlohmann::json report = refinement_report(r, o);
  EXPECT_EQ(report["held_out"]["chosen"], 30);
  EXPECT_EQ(report["held_out"]["views"].size(), 3u);
}

// The views it fits show other colours than the held-out ones: every iterate is worse than the
// start there, so the start comes back as it was given.
TEST(Refine, TheStartComesBackWhenNoIterateBeatsItOnTheHeldOutViews) {
  RefineOptions o = few_steps(20);
  o.hold_out_every = 2;
  std::vector<RefineView> views = views_across(grid(0.25f), 7);
  const std::vector<RefineView> truth = views_across(grid(), 7);
  for (int k : {2, 4, 6}) views[k] = truth[k];
  const RefineResult r = refine_gaussians(grid(), views, o);
  EXPECT_TRUE(r.kept_start);
  EXPECT_EQ(r.chosen_step, 0);
  ASSERT_EQ(r.iterates.size(), 3u);  // 0.7, 0.85 and the end
  for (const auto& [step, psnr] : r.iterates) EXPECT_LT(psnr, r.start_psnr) << step;
  EXPECT_TRUE(torch::equal(r.gaussians.means, grid().means));
  EXPECT_TRUE(torch::equal(r.gaussians.colors, grid().colors));
  EXPECT_EQ(refinement_report(r, o)["held_out"]["chosen"], "start");
}

// Views the start was made from are never held out; too few views left to fit: none is.
TEST(Refine, ContextViewsAreNotHeldOutNorAreViewsThatTheFitNeeds) {
  RefineOptions o = few_steps(2);
  o.hold_out_every = 2;
  std::vector<RefineView> views = views_across(grid(), 7);
  views[2].may_hold_out = false;
  EXPECT_EQ(refine_gaussians(grid(0.25f), views, o).held_out, (std::vector<std::string>{"v3", "v5"}));
  const RefineResult few = refine_gaussians(grid(0.25f), views_across(grid(), 3), o);
  EXPECT_TRUE(few.held_out.empty());
  EXPECT_EQ(few.views.size(), 3u);
  EXPECT_EQ(few.start_psnr, -1);
}

// Two 4 x 3 context views; the reference's region surface is its pixels 5 and 6 (the second view's
// mask, its pixel 5, is not the region). Each Gaussian's red is its row, so the split can be read
// off; they all sit at the reference camera's centre, which sees none of them, but one.
TEST(Refine, RefinementStartKeepsTheRegionAndItsCoverAndThinsTheRest) {
  Prediction p;
  for (int v = 0; v < 2; ++v) {
    PreparedView view;
    view.rgb = Image(4, 3, 3);
    view.mask = Image(4, 3, 1);
    p.input.views.push_back(view);
  }
  p.input.views[1].mask->at(1, 1) = 1;
  p.region_surface_pixels = torch::tensor({5, 6}, torch::kInt64);
  auto rows = [](int64_t n) {
    GaussianSet g;
    g.means = torch::zeros({n, 3});
    g.scales = torch::full({n, 3}, 0.1f);
    g.quats = torch::tensor({1.f, 0.f, 0.f, 0.f}).repeat({n, 1});
    g.opacities = torch::full({n}, 0.5f);
    g.colors = torch::zeros({n, 3});
    return g;
  };
  p.layers = {{"frame_margin", rows(9), {}}, {"behind_edges", rows(3), {}}, {"region_cover", rows(2), {}}};
  GaussianSet all = rows(24 + 9 + 3 + 2);
  all.colors.select(1, 0).copy_(torch::arange(all.size()).to(torch::kFloat32));
  auto xs = [](const GaussianSet& g) {
    std::vector<int64_t> out;
    for (int64_t i = 0; i < g.size(); ++i) out.push_back(static_cast<int64_t>(g.colors[i][0].item<float>()));
    return out;
  };
  const RefinementStart s = refinement_start(all, p, /*keep_object=*/false, 2);
  // Rows 0 and 2, columns 0 and 2 of each view; then every 4th past the frames and behind the edges.
  EXPECT_EQ(xs(s.moving), (std::vector<int64_t>{0, 2, 8, 10, 12, 14, 20, 22, 24, 28, 32}));
  EXPECT_EQ(xs(s.kept), (std::vector<int64_t>{5, 6, 36, 37}));
  // Without a region surface, the reference's mask is the region.
  p.region_surface_pixels = torch::Tensor();
  p.input.views[0].mask->at(0, 3) = 1;
  EXPECT_EQ(xs(refinement_start(all, p, false, 2).kept), (std::vector<int64_t>{3, 36, 37}));
  p.region_surface_pixels = torch::tensor({5, 6}, torch::kInt64);
  EXPECT_FLOAT_EQ(s.moving.scales[0][0].item<float>(), 0.2f);
  EXPECT_FLOAT_EQ(s.kept.scales[0][0].item<float>(), 0.1f);
  // Keeping the object: nothing is the region; the cover still stays as it is.
  EXPECT_EQ(xs(refinement_start(all, p, true, 1).kept), (std::vector<int64_t>{36, 37}));
  EXPECT_EQ(test::error_message([&] { refinement_start(rows(5), p, false, 2); }),
            "refine: 5 Gaussians do not match the prediction's 24 pixels");
  // Seen by the reference's camera (fx = fy = 1, no offset), every Gaussian at (1.5, -1.5, -3), on
  // its pixel (0, 1). Row 20 (the second view's) lies on the region, at pixel (1, 1) = 5: kept.
  Camera camera;
  camera.K.width = 4;
  camera.K.height = 3;
  camera.K.fx = camera.K.fy = 1;
  camera.K.cx = camera.K.cy = 0;
  p.input.input.view_cameras = {camera, camera};
  all.means.copy_(torch::tensor({1.5f, -1.5f, -3.f}).expand({all.size(), 3}));
  all.means[20] = torch::tensor({4.5f, -4.5f, -3.f});
  const RefinementStart seen = refinement_start(all, p, false, 2);
  EXPECT_EQ(xs(seen.kept), (std::vector<int64_t>{5, 6, 20, 36, 37}));
  EXPECT_EQ(xs(seen.moving), (std::vector<int64_t>{0, 2, 8, 10, 12, 14, 22, 24, 28, 32}));
  // After the run, a moved Gaussian that the reference sees in its region goes (row 20's place).
  int64_t dropped = -1;
  const GaussianSet outside = outside_the_region(all, p, false, &dropped);
  EXPECT_EQ(dropped, 1);
  EXPECT_EQ(outside.size(), all.size() - 1);
  EXPECT_EQ(xs(outside).at(20), 21);
  EXPECT_EQ(outside_the_region(all, p, true).size(), all.size());  // keeping the object: no region
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
                                  "--refine-position-rate 10 --keep-unrefined --threads 2 --out '" +
                                  tmp.string() + "'",
                              log),
            0)
      << test::file_bytes(log);
  const nlohmann::json run = nlohmann::json::parse(test::file_bytes(tmp / "run.json"));
  EXPECT_EQ(run["refine"]["steps"], 2);
  std::vector<std::string> views = run["refine"]["views"];
  const std::vector<std::string> scored = run["refine"]["held_out"]["views"];
  EXPECT_EQ(scored.size(), 3u);  // every 8th view but the context's chooses the result
  EXPECT_TRUE(run["refine"]["held_out"].contains("chosen"));  // the start or a step: SH 1 either way
  views.insert(views.end(), scored.begin(), scored.end());
  EXPECT_EQ(views.size(), 25u);  // every input view of the scene but 0, 8, 16, 24
  for (const char* held_out : {"IMG_2707", "IMG_2715", "IMG_2723", "IMG_2731"})
    EXPECT_EQ(std::find(views.begin(), views.end(), held_out), views.end()) << held_out;
  EXPECT_EQ(views[0], run["context"][0]);  // the reference first
  EXPECT_EQ(run["refine"]["losses"].size(), 2u);
  EXPECT_EQ(run["refine"]["sh_degree"], 1);
  EXPECT_NEAR(run["refine"]["position_rate"].get<double>(), 10, 1e-9);
  EXPECT_EQ(read_splat_ply(tmp / "gaussians.ply").sh_rest_per_channel, 3);
  EXPECT_EQ(read_splat_ply(tmp / "gaussians-unrefined.ply").sh_rest_per_channel, 0);
  EXPECT_NE(test::file_bytes(log).find("refine 100%  step 2"), std::string::npos) << test::file_bytes(log);
  EXPECT_EQ(run["refine"]["loss_chart"], "refine-loss.png");
  EXPECT_EQ(read_image_rgb(tmp / "refine-loss.png").width, 640);
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
