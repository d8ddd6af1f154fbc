// The synthetic scene generator: determinism, exact ground truth (clean = background render,
// mask = where the object changes the image), cameras on the object, reference degradation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "synth/random.h"
#include "synth/synth_scene.h"
#include "synth/synth_views.h"
#include "tensor/image_tensor.h"
#include "test_support.h"

namespace ii::synth {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace synth_scene_test {

SynthOptions tiny(ObjectSource source = ObjectSource::procedural) {
  SynthOptions o;
  o.views = 5;
  o.test_views = 2;
  o.width = 64;
  o.height = 48;
  o.object = source;
  return o;
}

bool same(const GaussianSet& a, const GaussianSet& b) {
  return a.size() == b.size() && torch::equal(a.means, b.means) && torch::equal(a.quats, b.quats) &&
         torch::equal(a.scales, b.scales) && torch::equal(a.opacities, b.opacities) && torch::equal(a.colors, b.colors);
}

TEST(SynthRng, FixedSequenceAndRanges) {
  SynthRng a(42), b(42), c(43);
  for (int i = 0; i < 100; ++i) {
    const double u = a.uniform();
    EXPECT_EQ(u, b.uniform());
    EXPECT_GE(u, 0.0);
    EXPECT_LT(u, 1.0);
    const int k = a.integer(-2, 3);
    EXPECT_EQ(k, b.integer(-2, 3));
    EXPECT_GE(k, -2);
    EXPECT_LE(k, 3);
  }
  EXPECT_NE(SynthRng(42).bits(), c.bits());
  // mt19937_64's 10000th output for the default seed is fixed by the C++ standard.
  SynthRng standard(5489u);
  uint64_t x = 0;
  for (int i = 0; i < 10000; ++i) x = standard.bits();
  EXPECT_EQ(x, 9981545732273789042ull);
  EXPECT_NE(mix_seed(1, 0), mix_seed(1, 1));
  EXPECT_NE(mix_seed(1, 0), mix_seed(2, 0));
}

TEST(SynthScene, SameSeedSameSceneOtherSeedOtherScene) {
  const SynthScene a = generate_scene(tiny(), 11);
  const SynthScene b = generate_scene(tiny(), 11);
  const SynthScene c = generate_scene(tiny(), 12);
  EXPECT_TRUE(same(a.background, b.background));
  EXPECT_TRUE(same(a.object, b.object));
  ASSERT_EQ(a.views.size(), 5u);
  ASSERT_EQ(a.test_views.size(), 2u);
  for (size_t i = 0; i < a.views.size(); ++i) EXPECT_EQ(a.views[i].camera.c2w, b.views[i].camera.c2w);
  EXPECT_EQ(a.description, b.description);
  EXPECT_FALSE(same(a.background, c.background));
  EXPECT_NE(a.views[0].camera.c2w, c.views[0].camera.c2w);
}

TEST(SynthScene, CamerasLookAtTheObjectWithLlffIntrinsics) {
  const SynthScene s = generate_scene(tiny(), 3);
  EXPECT_GT(s.background.size(), 1000);
  EXPECT_GT(s.object.size(), 100);
  EXPECT_EQ(s.context.size(), 4u);
  EXPECT_EQ(s.context.front(), s.reference);
  for (const auto& list : {s.views, s.test_views})
    for (const NamedCamera& v : list) {
      const Intrinsics& K = v.camera.K;
      EXPECT_EQ(K.width, 64);
      EXPECT_EQ(K.height, 48);
      EXPECT_DOUBLE_EQ(K.fx, K.fy);  // LLFF stores one focal length
      EXPECT_DOUBLE_EQ(K.cx, 32.0);
      EXPECT_DOUBLE_EQ(K.cy, 24.0);
      const Eigen::Vector4d x = v.camera.w2c_opencv() * s.object_centre.homogeneous();
      ASSERT_GT(x.z(), s.object_radius);  // in front, outside the object
      const double u = K.fx * x.x() / x.z() + K.cx, w = K.fy * x.y() / x.z() + K.cy;
      EXPECT_GT(u, 0.25 * K.width);
      EXPECT_LT(u, 0.75 * K.width);
      EXPECT_GT(w, 0.25 * K.height);
      EXPECT_LT(w, 0.75 * K.height);
    }
  // The object stays inside the room and all Gaussians are valid.
  EXPECT_TRUE(torch::isfinite(s.background.means).all().item<bool>());
  EXPECT_LE(s.background.opacities.max().item<float>(), 0.98f + 1e-6f);
  EXPECT_LE(s.object.opacities.max().item<float>(), 0.98f + 1e-6f);
  EXPECT_GE(s.object.colors.min().item<float>(), 0.f);
  EXPECT_LE(s.object.colors.max().item<float>(), 1.f);
}

// Cameras all around (--rings 2): every view looks at the object, their azimuths about it cover
// the whole circle evenly at two heights, the test views lie between them, and the context sees
// the object from four sides.
TEST(SynthScene, RingsPutTheCamerasAllAroundTheObject) {
  SynthOptions o = tiny();
  o.views = 12;
  o.test_views = 4;
  o.rings = 2;
  const SynthScene s = generate_scene(o, 3);
  auto azimuth = [&](const Camera& c) {
    const Eigen::Vector3d d = c.c2w.block<3, 1>(0, 3) - s.object_centre;
    return std::atan2(d.z(), d.x());
  };
  auto height = [&](const Camera& c) { return c.c2w(1, 3); };
  std::vector<double> azimuths;
  for (const NamedCamera& v : s.views) {
    const Eigen::Vector4d x = v.camera.w2c_opencv() * s.object_centre.homogeneous();
    ASSERT_GT(x.z(), s.object_radius) << v.name;
    const double u = v.camera.K.fx * x.x() / x.z() + v.camera.K.cx, w = v.camera.K.fy * x.y() / x.z() + v.camera.K.cy;
    EXPECT_NEAR(u, 32.0, 6.4) << v.name;  // the object in the middle of the picture
    EXPECT_NEAR(w, 24.0, 9.6) << v.name;
    azimuths.push_back(azimuth(v.camera));
  }
  std::sort(azimuths.begin(), azimuths.end());
  double widest = 2 * M_PI - (azimuths.back() - azimuths.front());
  for (size_t i = 1; i < azimuths.size(); ++i) widest = std::max(widest, azimuths[i] - azimuths[i - 1]);
  EXPECT_NEAR(widest, 2 * M_PI / 12, 0.02);  // evenly, all the way around
  EXPECT_LT(height(s.views[0].camera), height(s.views[1].camera));  // two rings, alternating
  EXPECT_NEAR(height(s.views[0].camera), height(s.views[2].camera), 1e-9);
  ASSERT_EQ(s.test_views.size(), 4u);
  EXPECT_EQ(s.context, (std::vector<int>{0, 3, 6, 9}));
  EXPECT_EQ(s.description["camera_path"]["rings"], 2);
  o.rings = 3;
  EXPECT_EQ(test::error_message([&] { generate_scene(o, 1); }), "synth: rings must be 0 (a path), 1 or 2 (got 3)");
}

class SynthViews : public ::testing::TestWithParam<uint64_t> {};

TEST_P(SynthViews, CleanIsTheBackgroundAndTheMaskIsWhereTheObjectChangesTheImage) {
  const SynthScene s = generate_scene(tiny(), GetParam());
  const SynthRenderer renderer(s);
  for (int k : {0, s.reference, static_cast<int>(s.views.size()) - 1}) {
    const Camera& cam = s.views[k].camera;
    const SynthViewImages r = renderer.render(cam);

    // The clean image is exactly a render of the background alone.
    RenderCamera rc;
    rc.camera = cam;
    RenderOptions options;
    options.background = s.render_background;
    const Image background = image_from_hwc(render(s.background, rc, options).rgb);
    EXPECT_EQ(background.pixels, r.clean.pixels);
    // The renderer culls and renders the object's neighbourhood only: still exactly the full
    // renders of the scene with the object and of the object-weight pass.
    GaussianSet all = combined_gaussians(s);
    const RenderOutput captured = render(all, rc, options);
    EXPECT_EQ(image_from_hwc(captured.rgb).pixels, r.with_object.pixels);
    EXPECT_EQ(image_from_hwc(captured.depth).pixels, r.depth.pixels);
    all.colors = torch::cat({torch::zeros({s.background.size(), 3}), torch::ones({s.object.size(), 3})});
    RenderOptions black = options;
    black.background = {0.f, 0.f, 0.f};
    EXPECT_EQ(image_from_hwc(render(all, rc, black).rgb.narrow(2, 0, 1)).pixels, r.object_weight.pixels);

    // |with - clean| <= W + slack per pixel and channel (synth_views.h); outside the mask
    // that is below threshold + slack.
    int masked = 0, strong = 0, strong_changed = 0;
    float worst_outside = 0;
    for (int y = 0; y < r.clean.height; ++y)
      for (int x = 0; x < r.clean.width; ++x) {
        const float w = r.object_weight.at(y, x);
        float diff = 0;
        for (int c = 0; c < 3; ++c) diff = std::max(diff, std::abs(r.with_object.at(y, x, c) - r.clean.at(y, x, c)));
        EXPECT_LE(diff, w + kEarlyStopSlack + 1e-5f) << "pixel " << x << "," << y;
        EXPECT_EQ(r.mask.at(y, x), w >= kMaskWeightThreshold ? 1.f : 0.f);
        if (r.mask.at(y, x) == 0.f) worst_outside = std::max(worst_outside, diff);
        masked += r.mask.at(y, x) > 0;
        if (w > 0.9f) {
          ++strong;
          strong_changed += diff > 0.01f;
        }
      }
    EXPECT_LE(worst_outside, kMaskWeightThreshold + kEarlyStopSlack + 1e-5f);
    // The object is seen, and where it covers the pixel the image does change.
    EXPECT_GT(masked, 20) << "view " << k;
    ASSERT_GT(strong, 10) << "view " << k;
    EXPECT_GT(strong_changed, strong * 0.8) << "view " << k;
  }
  // Test views: the clean image and the mask, no captured image.
  const SynthViewImages t = renderer.render(s.test_views[0].camera, false);
  EXPECT_TRUE(t.with_object.empty());
  EXPECT_FALSE(t.clean.empty());
  EXPECT_GT(std::count(t.mask.pixels.begin(), t.mask.pixels.end(), 1.f), 20);
}

INSTANTIATE_TEST_SUITE_P(Seeds, SynthViews, ::testing::Values(1, 2, 5));

TEST(SynthScene, SplatObjectStandsUprightOnItsSupport) {
  II_REQUIRE_SHARED(splats, "data/splats");
  SynthOptions o = tiny(ObjectSource::splat);
  o.splat_dir = splats;
  const SynthScene s = generate_scene(o, 4);
  EXPECT_EQ(s.description["object"]["kind"], "splat");
  EXPECT_GT(s.object.size(), 10000);
  const double height = s.description["object"]["height"];
  const torch::Tensor y = s.object.means.select(1, 1);
  const double base = s.description["support"].is_string() ? 0.0 : s.description["support"]["top"].get<double>();
  // The robust box spans [base, base + height]; floaters inside 5% margins remain.
  EXPECT_NEAR(y.quantile(0.005).item<double>(), base, 0.02 * height);
  EXPECT_NEAR(y.quantile(0.995).item<double>(), base + height, 0.02 * height);
  const SynthRenderer renderer(s);
  const SynthViewImages r = renderer.render(s.views[s.reference].camera);
  EXPECT_GT(std::count(r.mask.pixels.begin(), r.mask.pixels.end(), 1.f), 30);
}

TEST(SynthScene, SplatRequestedWithoutSplatsIsAnError) {
  SynthOptions o = tiny(ObjectSource::splat);
  o.splat_dir = "/nonexistent/splats";
  EXPECT_EQ(test::error_message([&] { generate_scene(o, 1); }),
            "synth: --object splat needs captured splats (*.ply) in '/nonexistent/splats'");
  // mixed falls back to procedural objects.
  o.object = ObjectSource::mixed;
  for (uint64_t seed = 0; seed < 4; ++seed)
    EXPECT_EQ(generate_scene(o, seed).description["object"]["kind"], "procedural");
}

TEST(SynthScene, RejectsBadOptions) {
  SynthOptions o = tiny();
  o.views = 3;
  EXPECT_EQ(test::error_message([&] { generate_scene(o, 1); }), "synth: need at least 4 views (got 3)");
  o = tiny();
  o.width = 8;
  EXPECT_EQ(test::error_message([&] { generate_scene(o, 1); }),
            "synth: image size must be between 16 and 8192 pixels a side (got 8x48)");
  EXPECT_EQ(test::error_message([] { parse_object_source("cube"); }),
            "--object: unknown object source 'cube' (expected procedural, splat or mixed)");
  EXPECT_EQ(test::error_message([] { parse_degradation("smear"); }),
            "--degrade: unknown degradation 'smear' (expected none, blur, color, noise, telea or mixed)");
}

TEST(DegradeReference, ChangesOnlyAroundTheMaskAndIsDeterministic) {
  Image clean(64, 64, 3), with_object(64, 64, 3), mask(64, 64, 1);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      for (int c = 0; c < 3; ++c) clean.at(y, x, c) = 0.5f + 0.4f * std::sin(0.7f * x + c) * std::cos(0.5f * y);
      const bool in = std::abs(x - 32) < 8 && std::abs(y - 32) < 8;
      mask.at(y, x) = in ? 1.f : 0.f;
      for (int c = 0; c < 3; ++c) with_object.at(y, x, c) = in ? 1.f : clean.at(y, x, c);
    }
  EXPECT_EQ(degrade_reference(clean, with_object, mask, Degradation::none, 1).pixels, clean.pixels);
  for (Degradation mode :
       {Degradation::blur, Degradation::color, Degradation::noise, Degradation::telea, Degradation::mixed}) {
    std::string applied;
    const Image a = degrade_reference(clean, with_object, mask, mode, 9, &applied);
    EXPECT_EQ(a.pixels, degrade_reference(clean, with_object, mask, mode, 9).pixels) << applied;
    EXPECT_FALSE(applied.empty());
    double inside = 0, far_outside = 0;
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x)
        for (int c = 0; c < 3; ++c) {
          const double d = std::abs(a.at(y, x, c) - clean.at(y, x, c));
          if (mask.at(y, x) > 0) inside = std::max(inside, d);
          // Dilation <= 2.5% of 64 px (2 px), feather sigma 1 px: nothing beyond 12 px.
          if (std::abs(x - 32) >= 20 || std::abs(y - 32) >= 20) far_outside = std::max(far_outside, d);
        }
    EXPECT_GT(inside, 0.01) << applied;
    EXPECT_LT(far_outside, 1e-6) << applied;
  }
}

}  // namespace synth_scene_test
}  // namespace
}  // namespace ii::synth
