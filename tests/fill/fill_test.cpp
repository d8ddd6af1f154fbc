// Filling the hole in a splat scene: the region chosen three ways, cameras, the fill itself
// (kept splats bit for bit, new ones in the scene's frame, the hole closer to the truth than
// deletion), refinement of the new splats alone, the CLI, and one clear message per bad input.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <fstream>

#include "camera/trajectory.h"
#include "common/error.h"
#include "eval/metrics.h"
#include "fill/fill.h"
#include "gaussians/gaussians.h"
#include "io/image.h"
#include "io/splat_file.h"
#include "render/projection.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"
#include "eval/synthetic_scene.h"
#include "model/scene_input.h"
#include "test_support.h"

namespace ii {
namespace {

using test::error_message;

// A floor (y = 0) with a smooth colour ramp, a back wall, and a red box standing on the floor
// at the origin. `under_box`: whether the floor goes on under the box (the truth after removal)
// or stops there (what a capture that never saw under the object holds).
SplatCloud room(bool with_box, bool under_box) {
  SplatCloud c;
  auto add = [&](double x, double y, double z, double r, double g, double b, Eigen::Vector3d scale) {
    c.means.insert(c.means.end(), {float(x), float(y), float(z)});
    for (double v : {r, g, b}) c.sh_dc.push_back(float(dc_of_colour(v)));
    c.opacity_logit.push_back(4.f);
    for (int k = 0; k < 3; ++k) c.log_scales.push_back(float(std::log(scale[k])));
    c.rotations.insert(c.rotations.end(), {1.f, 0.f, 0.f, 0.f});
  };
  const double step = 0.05;
  for (double x = -1.5; x <= 1.5 + 1e-9; x += step)
    for (double z = -1.5; z <= 1.5 + 1e-9; z += step) {
      if (!under_box && std::abs(x) < 0.25 && std::abs(z) < 0.25) continue;
      add(x, 0, z, 0.3 + 0.2 * (x + 1.5) / 3, 0.5, 0.4 + 0.2 * (z + 1.5) / 3, {0.035, 0.004, 0.035});
    }
  for (double x = -1.5; x <= 1.5 + 1e-9; x += step)
    for (double y = 0; y <= 1.5 + 1e-9; y += step) add(x, y, -1.5, 0.8, 0.8, 0.75, {0.035, 0.035, 0.004});
  if (with_box)
    for (double x = -0.2; x <= 0.2 + 1e-9; x += step)
      for (double y = 0.025; y <= 0.4 + 1e-9; y += step)
        for (double z = -0.2; z <= 0.2 + 1e-9; z += step) add(x, y, z, 0.8, 0.1, 0.1, {0.03, 0.03, 0.03});
  c.sh_rest_per_channel = 0;
  return c;
}

const OrientedBox kObjectBox = [] {
  OrientedBox b;
  b.centre = {0, 0.225, 0};
  b.size = {0.5, 0.43, 0.5};
  return b;
}();

Camera camera_at(const Eigen::Vector3d& eye, int width = 96, int height = 72) {
  Camera c;
  c.K = Intrinsics::from_fov(width, height, 2 * std::atan(std::tan(25 * M_PI / 180) * width / height), 50 * M_PI / 180);
  c.c2w = look_at(eye, {0, 0.1, 0}, {0, 1, 0});
  return c;
}

std::vector<NamedCamera> capture_cameras() {
  std::vector<NamedCamera> cameras;
  for (int i = 0; i < 6; ++i) {
    const double a = (i - 2.5) * 0.25;
    cameras.push_back({"cam" + std::to_string(i), camera_at({1.6 * std::sin(a), 1.1, 1.6 * std::cos(a)}, 128, 96)});
  }
  return cameras;
}

const Predictor& cpu_predictor() {
  static const Predictor predictor("", torch::kCPU, Precision::Float32);
  return predictor;
}

FillOptions box_fill(int views = 3) {
  FillOptions o;
  o.box = kObjectBox;
  o.camera_options.views = views;
  o.camera_options.height = 64;
  o.scene_name = "room.ply";
  return o;
}

// Two views of the capture's cameras, the new splats refined for 4 steps.
FillOptions capture_fill_refined() {
  FillOptions o = box_fill(2);
  o.cameras = capture_cameras();
  RefineOptions refine;
  refine.steps = 4;
  o.refine = refine;
  return o;
}

TEST(FillRegion, BoxesParseAndHoldTheirSplats) {
  const OrientedBox b = parse_box("0,0.225,0,0.5,0.43,0.5");
  EXPECT_EQ(b.centre, Eigen::Vector3d(0, 0.225, 0));
  EXPECT_TRUE(parse_box("1,2,3,1,1,1,0,45,0").contains({1, 2, 3.6}));   // the diagonal of a turned box reaches further
  EXPECT_FALSE(parse_box("1,2,3,1,1,1,0,0,0").contains({1, 2, 3.6}));
  EXPECT_EQ(error_message([] { parse_box("1,2,x,1,1,1"); }),
            "--box '1,2,x,1,1,1': 'x' is not a number (expected cx,cy,cz,sx,sy,sz[,rx,ry,rz])");
  EXPECT_EQ(error_message([] { parse_box("1,2,3,1,1"); }),
            "--box '1,2,3,1,1': 5 numbers, expected 6 (centre, size) or 9 (centre, size, rotation in degrees)");
  EXPECT_EQ(error_message([] { parse_box("1,2,3,1,0,1"); }), "--box '1,2,3,1,0,1': the size must be positive along every axis");

  const SplatCloud with = room(true, false), without = room(false, false);
  EXPECT_EQ(region_count(region_in_box(with, kObjectBox)), static_cast<int64_t>(with.size() - without.size()));
}

TEST(FillRegion, ASelectionFileNamesTheSplatsItLacks) {
  const SplatCloud with = room(true, false), without = room(false, false);
  const RegionMask exact = region_missing_from(with, without, "without.ply");
  EXPECT_EQ(exact, region_in_box(with, kObjectBox));
  // Re-quantised positions (a compressed format's) match by the nearest.
  SplatCloud moved = without;
  for (float& v : moved.means) v += 2e-5f;
  EXPECT_EQ(region_missing_from(with, moved, "moved.ply"), exact);
  SplatCloud other = without;
  for (float& v : other.means) v += 0.5f;
  EXPECT_EQ(error_message([&] { region_missing_from(with, other, "other.ply"); }),
            fmt::format("--selection other.ply: {} of its {} splats are not in the scene: it is not this scene with "
                        "some splats deleted",
                        other.size(), other.size()));
}

TEST(FillRegion, AStrokeSelectsTheSurfaceItCoversAndWhatIsBehindIt) {
  const SplatCloud with = room(true, false);
  const Camera camera = camera_at({0, 0.9, 1.6});
  // The stroke: where the box is seen (its splats' render), as a user would paint over it.
  const RegionMask truth = region_in_box(with, kObjectBox);
  GaussianSet g = gaussians_from_splats(with, 0);
  std::vector<float> w(truth.begin(), truth.end());
  g.colors = torch::tensor(w).unsqueeze(1).expand({g.size(), 3}).contiguous();
  g.sh_degree = -1;
  RenderOptions black;
  black.background = {0, 0, 0};
  const Image stroke = image_from_hwc((render(g, {camera}, black).rgb.narrow(2, 0, 1) > 0.5).to(torch::kFloat32));
  const RegionMask picked = region_under_stroke(with, camera, stroke);
  int64_t both = 0;
  for (size_t i = 0; i < truth.size(); ++i) both += truth[i] && picked[i];
  EXPECT_GT(double(both) / double(region_count(truth)), 0.95);   // the box, its back too
  EXPECT_GT(double(both) / double(region_count(picked)), 0.75);  // and little of the floor around it
  EXPECT_EQ(error_message([&] { region_under_stroke(with, camera, Image(10, 10, 1)); }),
            "--mask: 10x10 pixels, but the view's camera is 96x72");
  EXPECT_EQ(error_message([&] { region_under_stroke(with, camera, Image(96, 72, 1)); }),
            "--mask: the stroke covers no surface of the scene in this view (nothing is drawn there)");
}

// One click on the front of the room's box from `camera`: what it selects, the box's splats, how many
// of them it selects and how many of the back wall's.
struct ClickOnTheBox {
  RegionMask picked, truth;
  int64_t both = 0, wall = 0;
};
ClickOnTheBox click_on_the_box(const SplatCloud& with, const Camera& camera) {
  ClickOnTheBox c;
  const std::optional<PixelOfPoint> front = pixel_of_point(camera.K, camera.w2c_opencv(), {0.05, 0.2, 0.2});
  EXPECT_TRUE(front);
  if (!front) return c;
  c.picked = region_from_clicks(with, camera, "cam", {{front->x + 0.5, front->y + 0.5}});
  c.truth = region_in_box(with, kObjectBox);
  for (size_t i = 0; i < c.truth.size(); ++i) {
    c.both += c.truth[i] && c.picked[i];
    c.wall += c.picked[i] && with.means[3 * i + 2] < -1.4f;
  }
  return c;
}

// One click on the box: its splats, all of them (its hidden back too), and little of the floor it
// stands on (what the box's outline hides of it) and nothing of the wall behind it.
TEST(FillRegion, AClickSelectsTheObjectAndNotWhatItStandsOn) {
  const SplatCloud with = room(true, false);
  const Camera camera = camera_at({0, 0.9, 1.6});
  const ClickOnTheBox c = click_on_the_box(with, camera);
  const RegionMask& picked = c.picked;
  const RegionMask& truth = c.truth;
  const int64_t both = c.both, wall = c.wall;
  EXPECT_EQ(both, region_count(truth));
  EXPECT_GT(double(both) / double(region_count(picked)), 0.75);
  EXPECT_EQ(wall, 0);
  EXPECT_EQ(error_message([&] { region_from_clicks(with, camera, "cam", {{-1, 5}}); }),
            "the click (-1, 5) is outside view cam's image (96x72)");
}

// A trained file's box of two colours (red below, blue above; translucent splats, as 3DGS's):
// the click on the red grows over the red alone in the render; the rest of the object, joined to
// it by like depths above the floor it stands on, comes with it, and the floor does not.
TEST(FillRegion, AClickOnOneColourOfAnObjectSelectsItWhole) {
  SplatCloud with = room(true, false);
  const RegionMask truth = region_in_box(with, kObjectBox);
  for (size_t i = 0; i < with.size(); ++i)
    if (truth[i] && with.means[3 * i + 1] > 0.22f)
      for (int c = 0; c < 3; ++c) with.sh_dc[3 * i + c] = float(dc_of_colour(std::array<double, 3>{0.1, 0.2, 0.9}[c]));
  std::mt19937 rng(23);
  std::normal_distribution<float> jitter(0.f, 0.35f);
  for (float& l : with.opacity_logit) l = -1.2f;  // opacity 0.23
  for (float& s : with.log_scales) s += std::log(1.6f);
  for (float& dc : with.sh_dc) dc += jitter(rng);  // unlike splat by splat: the render's path
  const Camera camera = camera_at({0, 0.9, 1.6}, 192, 144);
  const std::optional<PixelOfPoint> red = pixel_of_point(camera.K, camera.w2c_opencv(), {0.05, 0.1, 0.2});
  ASSERT_TRUE(red);
  const RegionMask picked = region_from_clicks(with, camera, "cam", {{red->x + 0.5, red->y + 0.5}});
  int64_t both = 0, floor = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    both += truth[i] && picked[i];
    floor += picked[i] && !truth[i];
  }
  EXPECT_GT(double(both) / double(region_count(truth)), 0.9);
  EXPECT_GT(double(both) / double(region_count(picked)), 0.75) << floor << " others";
}

// A trained file's splats are translucent and unlike in colour splat by splat (3DGS, reconstruct):
// growing over them stops at once. The click is then taken in their render as in a photo: the box
// again, and nothing of the wall.
TEST(FillRegion, AClickOnTranslucentSplatsSelectsTheObjectInTheirRender) {
  SplatCloud with = room(true, false);
  std::mt19937 rng(17);
  std::normal_distribution<float> jitter(0.f, 0.35f);
  for (float& l : with.opacity_logit) l = -1.2f;  // opacity 0.23
  for (float& s : with.log_scales) s += std::log(1.6f);
  for (float& dc : with.sh_dc) dc += jitter(rng);
  const Camera camera = camera_at({0, 0.9, 1.6}, 192, 144);
  const ClickOnTheBox c = click_on_the_box(with, camera);
  const RegionMask& picked = c.picked;
  const RegionMask& truth = c.truth;
  const int64_t both = c.both, wall = c.wall;
  EXPECT_GT(double(both) / double(region_count(truth)), 0.9) << both << " of " << region_count(truth);
  EXPECT_GT(double(both) / double(region_count(picked)), 0.7) << region_count(picked) << " picked";
  EXPECT_EQ(wall, 0);
}

// A trained file's stack seen from above (splats part translucent, as 3DGS's): a small red top on a wide
// blue base, and under the base, below the floor's surface, blue splats (no camera saw there;
// training leaves the object's colours there). One click on the top takes the base, whose depths
// lie behind the top's by more than the top is wide, and the blue splats under it; the floor
// around stays.
TEST(FillRegion, AClickOnTheTopOfAStackTakesItsBaseAndTheObjectsColoursUnderIt) {
  SplatCloud with = room(false, false);
  const size_t floor_and_wall = with.size();
  auto add = [&](double x, double y, double z, std::array<double, 3> rgb) {
    with.means.insert(with.means.end(), {float(x), float(y), float(z)});
    for (double v : rgb) with.sh_dc.push_back(float(dc_of_colour(v)));
    with.opacity_logit.push_back(4.f);
    for (int k = 0; k < 3; ++k) with.log_scales.push_back(std::log(0.03f));
    with.rotations.insert(with.rotations.end(), {1.f, 0.f, 0.f, 0.f});
  };
  const double step = 0.05;
  for (double x = -0.2; x <= 0.2 + 1e-9; x += step)
    for (double z = -0.2; z <= 0.2 + 1e-9; z += step) {
      for (double y = 0.025; y <= 0.175 + 1e-9; y += step) add(x, y, z, {0.1, 0.2, 0.9});
      add(x, -0.004, z, {0.1, 0.2, 0.9});
    }
  for (double x = -0.075; x <= 0.075 + 1e-9; x += step)
    for (double y = 0.225; y <= 0.325 + 1e-9; y += step)
      for (double z = -0.075; z <= 0.075 + 1e-9; z += step) add(x, y, z, {0.9, 0.1, 0.1});
  std::mt19937 rng(29);
  std::normal_distribution<float> jitter(0.f, 0.35f);
  for (float& l : with.opacity_logit) l = 0.5f;  // opacity 0.62
  for (float& dc : with.sh_dc) dc += jitter(rng);  // unlike splat by splat: the render's path
  const Camera camera = camera_at({0, 0.9, 1.6}, 192, 144);
  const std::optional<PixelOfPoint> red = pixel_of_point(camera.K, camera.w2c_opencv(), {0, 0.3, 0.075});
  ASSERT_TRUE(red);
  const RegionMask picked = region_from_clicks(with, camera, "cam", {{red->x + 0.5, red->y + 0.5}});
  int64_t object = 0, object_picked = 0, under = 0, under_picked = 0, others = 0;
  for (size_t i = floor_and_wall; i < with.size(); ++i) {
    const bool below_the_floor = with.means[3 * i + 1] < 0;
    (below_the_floor ? under : object) += 1;
    (below_the_floor ? under_picked : object_picked) += picked[i];
  }
  for (size_t i = 0; i < floor_and_wall; ++i) others += picked[i];
  EXPECT_GT(double(object_picked) / double(object), 0.9) << object_picked << " of " << object;
  EXPECT_GT(double(under_picked) / double(under), 0.8) << under_picked << " of " << under;
  EXPECT_LT(double(others), 0.02 * double(floor_and_wall)) << others << " of " << floor_and_wall;
}

// With a segmenter (the small MobileSAM-layout fixture of tests/segment), a click prompts it on
// the scene's render from the camera, and its outline is taken as a stroke: the region is the
// stroke's, and the record names the mask it chose.
TEST(FillRegion, ASegmentersOutlineOfTheRenderIsTakenAsAStroke) {
  const SplatCloud with = room(true, false);
  const Camera camera = camera_at({0, 0.9, 1.6});
  const Segmenter segmenter = Segmenter::load("tests/segment/fixture/mobile_sam_small.pt", SegmenterPrecision::Float32);
  const std::optional<PixelOfPoint> front = pixel_of_point(camera.K, camera.w2c_opencv(), {0.05, 0.2, 0.2});
  ASSERT_TRUE(front);
  const std::vector<Click> clicks = {{front->x + 0.5, front->y + 0.5}};
  ClickedMask clicked;
  const RegionMask picked = region_from_segmented_clicks(with, camera, "cam", clicks, {}, segmenter, &clicked);
  EXPECT_GT(clicked.pixels, 0);
  EXPECT_EQ(clicked.scores.size(), 3u);
  torch::NoGradGuard no_grad;
  const Image seen = image_from_hwc(render(gaussians_from_splats(with, 0), {camera}).rgb);
  const ClickedMask again = mask_from_clicks(segmenter, seen, clicks, {});
  EXPECT_EQ(again.mask.pixels, clicked.mask.pixels);
  EXPECT_EQ(picked, region_under_stroke(with, camera, again.mask));
  EXPECT_EQ(error_message([&] { region_from_segmented_clicks(with, camera, "cam", clicks, {{200, 5}}, segmenter); }),
            "the click (200, 5) is outside view cam's image (96x72)");
}

// A box around the object on a camera's view, without a segmenter: GrabCut in the splats' render
// from that camera, taken as a stroke: the box's splats, its hidden back too, and nothing of the
// wall behind it. Bad boxes say what is wrong.
TEST(FillRegion, ABoxOnTheRenderSelectsTheObjectByGrabCut) {
  const SplatCloud with = room(true, false);
  const Camera camera = camera_at({0, 0.9, 1.6});
  // The object's box (kObjectBox) as the camera sees it, grown by a pixel (about 7 % of its 26 x 30).
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (double x : {-0.2, 0.2})
    for (double y : {0.0, 0.44})
      for (double z : {-0.2, 0.2}) {
        const std::optional<PixelOfPoint> p = pixel_of_point(camera.K, camera.w2c_opencv(), {x, y, z});
        ASSERT_TRUE(p);
        x0 = std::min<double>(x0, p->x), y0 = std::min<double>(y0, p->y);
        x1 = std::max<double>(x1, p->x + 1), y1 = std::max<double>(y1, p->y + 1);
      }
  const ViewBox box{x0 - 1, y0 - 1, x1 + 1, y1 + 1};
  const RegionMask picked = region_from_view_box(with, camera, "cam", box, {}, {}, nullptr);
  const RegionMask truth = region_in_box(with, kObjectBox);
  int64_t both = 0, wall = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    both += truth[i] && picked[i];
    wall += picked[i] && with.means[3 * i + 2] < -1.4f;
  }
  EXPECT_GT(double(both) / double(region_count(truth)), 0.95);
  EXPECT_GT(double(both) / double(region_count(picked)), 0.75);
  EXPECT_EQ(wall, 0);
  EXPECT_EQ(error_message([&] { region_from_view_box(with, camera, "cam", {10, 10, 100, 50}, {}, {}, nullptr); }),
            "view cam: the box 10,10,100,50 reaches outside its photo (96x72)");
  EXPECT_EQ(error_message([&] { region_from_view_box(with, camera, "cam", box, {{1, 1}}, {}, nullptr); }),
            fmt::format("view cam: the click (1, 1) is outside the box {:g},{:g},{:g},{:g}: clicks with a box are on "
                        "the object inside it",
                        box[0], box[1], box[2], box[3]));
}

TEST(FillCameras, GivenCamerasThatSeeTheRegionBestComeFirst) {
  const SplatCloud with = room(true, false);
  std::vector<NamedCamera> cameras = capture_cameras();
  cameras.push_back({"away", camera_at({0, 1, 1.6})});
  cameras.back().camera.c2w = look_at({0, 1, 1.6}, {0, 1, 5}, {0, 1, 0});  // looks out of the room
  FillCameraOptions options;
  options.views = 3;
  options.height = 64;
  const ChosenCameras chosen = choose_given_cameras(gaussians_from_splats(with, 0), region_in_box(with, kObjectBox), cameras, options);
  ASSERT_EQ(chosen.cameras.size(), 3u);
  for (const NamedCamera& c : chosen.cameras) {
    EXPECT_NE(c.name, "away");
    EXPECT_EQ(c.camera.K.height, 64);
    EXPECT_EQ(c.camera.K.width % 8, 0);
  }
  EXPECT_GE(chosen.visible[0], chosen.visible[1]);
  const std::vector<NamedCamera> blind = {cameras.back()};
  EXPECT_EQ(error_message([&] {
              choose_given_cameras(gaussians_from_splats(with, 0), region_in_box(with, kObjectBox), blind, options);
            }),
            "none of the 1 cameras sees the region (its centre (0, 0.2, 0) is outside every view, or hidden): give "
            "cameras that see it, or none (automatic views)");
}

// Cameras all round the box on a floor that goes on under it (what a trained file holds there):
// behind the box each camera's surface is the floor, seen from the other sides except under the
// box, where no camera looked; a thin wall seen from its inside through a hole is not seen.
TEST(FillCameras, TheSurfaceBehindTheRegionIsSeenFromTheOtherSidesExceptUnderIt) {
  const SplatCloud with = room(true, true);
  std::vector<NamedCamera> ring;
  for (int i = 0; i < 12; ++i) {
    const double a = 2 * M_PI * i / 12;
    ring.push_back({"ring" + std::to_string(i), camera_at({1.2 * std::sin(a), 0.9, 1.2 * std::cos(a)}, 128, 96)});
  }
  FillCameraOptions options;
  options.height = 64;
  const ChosenCameras chosen =
      choose_given_cameras(gaussians_from_splats(with, 0), region_in_box(with, kObjectBox), ring, options);
  ASSERT_TRUE(chosen.captured);
  ASSERT_EQ(chosen.sights.size(), 12u);
  int64_t under = 0, under_seen = 0, beside = 0, beside_seen = 0;
  for (const Sight& s : chosen.sights) {
    ASSERT_TRUE(s.kept_depth.defined() && s.kept_seen.defined() && s.share.defined());
    const torch::Tensor behind = (s.share > 0.5).logical_and(s.kept_depth > 0);
    const torch::Tensor pixels = behind.nonzero();
    const torch::Tensor world = unproject(s.camera, pixels.select(1, 0).to(torch::kFloat64),
                                          pixels.select(1, 1).to(torch::kFloat64),
                                          s.kept_depth.index({behind}).to(torch::kFloat64));
    const torch::Tensor seen = s.kept_seen.index({behind});
    // under the box (0.4 wide) with a margin for the pixels' size; beside it: clear of that
    const torch::Tensor x = world.select(1, 0).abs(), z = world.select(1, 2).abs();
    const torch::Tensor is_under = (x < 0.15).logical_and(z < 0.15);
    const torch::Tensor is_beside = (x > 0.3).logical_or(z > 0.3);
    under += is_under.sum().item<int64_t>();
    under_seen += is_under.logical_and(seen).sum().item<int64_t>();
    beside += is_beside.sum().item<int64_t>();
    beside_seen += is_beside.logical_and(seen).sum().item<int64_t>();
  }
  ASSERT_GT(under, 0);
  ASSERT_GT(beside, 0);
  EXPECT_EQ(under_seen, 0) << "of " << under;
  EXPECT_GT(beside_seen, beside * 8 / 10) << "of " << beside;
}

TEST(FillCameras, AutomaticCamerasLookAtTheRegionFromAbove) {
  const SplatCloud with = room(true, false);
  const RegionMask region = region_in_box(with, kObjectBox);
  const Eigen::Vector3d up = guess_up(with, region);
  EXPECT_EQ(up, Eigen::Vector3d(0, 1, 0));  // the room is thinnest along y, the box stands on the floor
  FillCameraOptions options;
  options.up = up;
  options.height = 64;
  const ChosenCameras chosen = choose_automatic_cameras(gaussians_from_splats(with, 0), region, options);
  ASSERT_EQ(chosen.cameras.size(), 4u);
  for (const NamedCamera& c : chosen.cameras) {
    EXPECT_GT(c.camera.center().y(), 0.1) << c.name;   // above the floor
    EXPECT_GT(c.camera.center().z(), -1.5) << c.name;  // in front of the wall
  }
}

TEST(Fill, KeepsEverySplatBitForBitAndFillsTheHoleInTheScenesFrame) {
  const SplatCloud with = room(true, false);
  const FillOptions options = box_fill();
  const FillResult r = fill_splats(with, options, cpu_predictor());
  const RegionMask region = region_in_box(with, kObjectBox);
  EXPECT_EQ(r.removed, region_count(region));
  EXPECT_GT(r.added, 0);
  ASSERT_EQ(r.splats.size(), with.size() - r.removed + r.added);
  // The kept splats first, in their order, every value as it was.
  size_t k = 0;
  for (size_t i = 0; i < with.size(); ++i) {
    if (region[i]) continue;
    for (int c = 0; c < 3; ++c) ASSERT_EQ(r.splats.means[3 * k + c], with.means[3 * i + c]);
    for (int c = 0; c < 4; ++c) ASSERT_EQ(r.splats.rotations[4 * k + c], with.rotations[4 * i + c]);
    ASSERT_EQ(r.splats.opacity_logit[k], with.opacity_logit[i]);
    ++k;
  }
  // The new ones where the hole is, in the scene's frame: near the floor under the box.
  int64_t near_hole = 0;
  for (size_t i = with.size() - r.removed; i < r.splats.size(); ++i) {
    const Eigen::Vector3d p(r.splats.means[3 * i], r.splats.means[3 * i + 1], r.splats.means[3 * i + 2]);
    near_hole += std::abs(p.x()) < 0.6 && std::abs(p.z()) < 0.6 && p.y() > -0.3 && p.y() < 0.5;
  }
  EXPECT_GT(double(near_hole) / double(r.added), 0.8);
  EXPECT_EQ(r.before.size(), 3u);
  EXPECT_EQ(r.report()["splats"]["removed"], r.removed);
  EXPECT_GT(r.stages.waited_ms(), 0);
}

TEST(Fill, TheHoleComesCloserToTheTruthThanDeletionAlone) {
  const SplatCloud with = room(true, false), truth_cloud = room(false, true);
  const FillResult r = fill_splats(with, box_fill(), cpu_predictor());
  const GaussianSet truth = gaussians_from_splats(truth_cloud, 0);
  double deleted_error = 0, filled_error = 0;
  for (size_t v = 0; v < r.after.size(); ++v) {
    const torch::Tensor mask = image_to_tensor(r.masks[v]) > 0.5;
    const torch::Tensor t = image_to_tensor(image_from_hwc(render(truth, {r.cameras.cameras[v].camera}).rgb));
    auto error = [&](const Image& image) { return (image_to_tensor(image) - t).abs().mean(1, true).index({mask}).mean().item<double>(); };
    deleted_error += error(r.deleted[v]);
    filled_error += error(r.after[v]);
  }
  EXPECT_LT(filled_error, 0.6 * deleted_error) << "deleted " << deleted_error << ", filled " << filled_error;
}

// Cameras all round the box (a capture made for splats): what one side hides the others saw, so
// the new splats lie on the floor under the box alone, where no camera looked; none stands in
// space a camera saw through.
TEST(Fill, OnACaptureAllRoundTheNewSplatsLieWhereNoCameraLooked) {
  FillOptions o = box_fill(4);
  for (int i = 0; i < 12; ++i) {
    const double a = 2 * M_PI * i / 12;
    o.cameras.push_back({"ring" + std::to_string(i), camera_at({1.2 * std::sin(a), 0.9, 1.2 * std::cos(a)}, 128, 96)});
  }
  const FillResult r = fill_splats(room(true, false), o, cpu_predictor());
  ASSERT_GT(r.added, 0);
  const size_t first_new = r.splats.size() - static_cast<size_t>(r.added);
  int64_t off_the_footprint = 0;
  for (size_t i = first_new; i < r.splats.size(); ++i) {
    const float x = r.splats.means[3 * i], y = r.splats.means[3 * i + 1], z = r.splats.means[3 * i + 2];
    // the footprint (the box is 0.45 wide) and the seam of the floor's own colours around it
    off_the_footprint += std::abs(y) > 0.05f || std::abs(x) > 0.5f || std::abs(z) > 0.5f;
  }
  EXPECT_EQ(off_the_footprint, 0) << "of " << r.added << " new splats";
}

// Cameras all round the box, and the floor goes on under it (a capture's training continues a
// surface under what stands on it): the hole keeps that floor, nothing is painted over it; with
// the cameras on one side (not round the region) the hole is painted as before.
TEST(Fill, OnACaptureAllRoundTheSurfaceUnderTheObjectIsKept) {
  FillOptions o = box_fill(4);
  for (int i = 0; i < 12; ++i) {
    const double a = 2 * M_PI * i / 12;
    o.cameras.push_back({"ring" + std::to_string(i), camera_at({1.2 * std::sin(a), 0.9, 1.2 * std::cos(a)}, 128, 96)});
  }
  const SplatCloud with = room(true, true);
  const FillResult round = fill_splats(with, o, cpu_predictor());
  EXPECT_TRUE(round.cameras.round);
  EXPECT_EQ(round.added, 0);
  o.cameras = capture_cameras();
  const FillResult one_side = fill_splats(with, o, cpu_predictor());
  EXPECT_FALSE(one_side.cameras.round);
  EXPECT_GT(one_side.added, 0);
}

// The surface placement (the default): in every chosen view each hole pixel renders something,
// and the hole is nearer the truth than the network's placement in this room.
TEST(Fill, TheSurfacePlacementCoversEveryHolePixelOfItsViews) {
  const SplatCloud with = room(true, false), truth_cloud = room(false, true);
  const GaussianSet truth = gaussians_from_splats(truth_cloud, 0);
  FillOptions options = box_fill();
  options.cameras = capture_cameras();
  ASSERT_EQ(options.placement, FillPlacement::surface);
  const FillResult surface = fill_splats(with, options, cpu_predictor());
  EXPECT_EQ(surface.report()["placement"], "surface");
  const GaussianSet filled = gaussians_from_splats(surface.splats, 0);
  double surface_error = 0;
  for (size_t v = 0; v < surface.cameras.cameras.size(); ++v) {
    const Camera& camera = surface.cameras.cameras[v].camera;
    const torch::Tensor hole = image_to_tensor(surface.masks[v])[0][0] > 0.5;
    ASSERT_GT(hole.sum().item<int64_t>(), 0);
    const torch::Tensor alpha = render(filled, {camera}).alpha.squeeze(2);
    EXPECT_EQ(alpha.index({hole}).lt(0.5).sum().item<int64_t>(), 0) << "uncovered hole pixels in view " << v;
    const torch::Tensor t = image_to_tensor(image_from_hwc(render(truth, {camera}).rgb));
    surface_error += (image_to_tensor(surface.after[v]) - t).abs().mean(1, true).index({hole.unsqueeze(0).unsqueeze(0)}).mean().item<double>();
  }
  options.placement = FillPlacement::network;
  const FillResult network = fill_splats(with, options, cpu_predictor());
  double network_error = 0;
  for (size_t v = 0; v < network.cameras.cameras.size(); ++v) {
    const torch::Tensor hole = image_to_tensor(network.masks[v]) > 0.5;
    const torch::Tensor t = image_to_tensor(image_from_hwc(render(truth, {network.cameras.cameras[v].camera}).rgb));
    network_error += (image_to_tensor(network.after[v]) - t).abs().mean(1, true).index({hole}).mean().item<double>();
  }
  EXPECT_LT(surface_error, network_error) << "surface " << surface_error << ", network " << network_error;
}

// Renders read near the region alone draw only the splats that reach it there: the filled
// scene is the same, value for value, as with every splat drawn.
TEST(Fill, CullingTheRendersChangesNothing) {
  const SplatCloud with = room(true, false);
  FillOptions options = box_fill();
  options.cameras = capture_cameras();
  ASSERT_TRUE(options.camera_options.cull);
  const FillResult culled = fill_splats(with, options, cpu_predictor());
  options.camera_options.cull = false;
  const FillResult whole = fill_splats(with, options, cpu_predictor());
  ASSERT_EQ(culled.splats.size(), whole.splats.size());
  EXPECT_EQ(culled.splats.means, whole.splats.means);
  EXPECT_EQ(culled.splats.sh_dc, whole.splats.sh_dc);
  EXPECT_EQ(culled.splats.log_scales, whole.splats.log_scales);
  EXPECT_EQ(culled.splats.opacity_logit, whole.splats.opacity_logit);
  EXPECT_EQ(culled.reference.pixels, whole.reference.pixels);
  // The pictures too: near the region drawn from the splats that reach it, the rest from the
  // removed scene's picture.
  ASSERT_EQ(culled.after.size(), whole.after.size());
  for (size_t v = 0; v < whole.after.size(); ++v) {
    EXPECT_EQ(culled.before[v].pixels, whole.before[v].pixels) << "view " << v;
    EXPECT_EQ(culled.after[v].pixels, whole.after[v].pixels) << "view " << v;
    EXPECT_EQ(culled.masks[v].pixels, whole.masks[v].pixels) << "view " << v;
  }
}

// A window's splats: a render of those reaching it equals the whole set's there, and far fewer
// are drawn when the window is small.
TEST(FillCameras, TheSplatsReachingAWindowDrawItAsTheWholeSetDoes) {
  const GaussianSet scene = gaussians_from_splats(room(true, false), 0);
  const Camera camera = capture_cameras()[2].camera;
  const PixelWindow window{40, 30, 80, 60};
  const torch::Tensor reach = reaching_window(scene, camera, window);
  EXPECT_LT(reach.sum().item<int64_t>(), scene.size() / 2);
  const torch::Tensor all = render(scene, {camera}).rgb, some = render(select_rows(scene, reach), {camera}).rgb;
  const torch::Tensor inside = all.slice(0, 30, 60).slice(1, 40, 80) - some.slice(0, 30, 60).slice(1, 40, 80);
  EXPECT_LT(inside.abs().max().item<double>(), 1e-6);
  EXPECT_GT((all - some).abs().max().item<double>(), 0.1) << "outside the window the culled render differs";
}

// A stroke's view is the reference unless another is named; a reference painted on it may come
// at the working size of the official evaluation (512 rows, cropped) while the fill works at 64.
TEST(Fill, TheStrokesViewIsTheReferenceAndItsPictureMayComeAtEvalsSize) {
  const SplatCloud with = room(true, false);
  FillOptions options = box_fill(2);
  options.box.reset();
  options.cameras = capture_cameras();
  const NamedCamera& drawn_on = options.cameras[4];
  options.stroke_view = drawn_on.name;
  Image stroke(drawn_on.camera.K.width, drawn_on.camera.K.height, 1);
  const PixelHit centre = project(drawn_on.camera, torch::tensor({{0.0, 0.2, 0.0}}, torch::kFloat64));
  const int64_t at = centre.index[0].item<int64_t>();
  const int cy = static_cast<int>(at / stroke.width), cx = static_cast<int>(at % stroke.width);
  for (int y = 0; y < stroke.height; ++y)
    for (int x = 0; x < stroke.width; ++x) stroke.at(y, x) = std::hypot(x - cx, y - cy) < 6 ? 1.f : 0.f;
  options.stroke = stroke;
  // 128x96 at 512 rows: 682 wide, cropped to 680.
  options.reference_image = Image(680, 512, 3, 0.25f);
  const FillResult r = fill_splats(with, options, cpu_predictor());
  EXPECT_EQ(r.cameras.cameras.at(0).name, drawn_on.name);
  EXPECT_EQ(r.report()["cameras"]["reference"], drawn_on.name);
  EXPECT_GT(r.added, 0);
  options.reference_image = Image(100, 77, 3, 0.25f);
  EXPECT_EQ(error_message([&] { fill_splats(with, options, cpu_predictor()); }),
            "--reference: 100x77 pixels, but the reference view cam4 is 80x64 at the working size and 128x96 as given "
            "(or that photo's working size at another height, as eval's)");
}

TEST(Fill, RefinementMovesTheNewSplatsAloneAndKeepsTheRest) {
  const SplatCloud with = room(true, false);
  const FillOptions options = capture_fill_refined();
  const FillResult r = fill_splats(with, options, cpu_predictor());
  EXPECT_EQ(r.cameras.how.rfind("given", 0), 0u);
  EXPECT_EQ(r.refine_report["steps"], 4);
  const RegionMask region = region_in_box(with, kObjectBox);
  size_t k = 0;
  for (size_t i = 0; i < with.size(); ++i)
    if (!region[i]) {
      ASSERT_EQ(r.splats.means[3 * k++], with.means[3 * i]);
    }
  EXPECT_GT(r.added, 0);
}

TEST(Fill, BadRegionsAndFilesSayWhatIsWrong) {
  const SplatCloud with = room(true, false);
  FillOptions nothing = box_fill();
  nothing.box = parse_box("5,5,5,0.1,0.1,0.1");
  EXPECT_EQ(error_message([&] { fill_splats(with, nothing, cpu_predictor()); }),
            "the box (centre (5, 5, 5), size (0.1, 0.1, 0.1)) holds no splat of room.ply: its splats lie within "
            "x -1.5 to 1.5, y 0 to 1.45, z -1.5 to 1.45");
  FillOptions everything = box_fill();
  everything.box = parse_box("0,0,0,10,10,10");
  EXPECT_EQ(error_message([&] { fill_splats(with, everything, cpu_predictor()); }),
            fmt::format("the box (centre (0, 0, 0), size (10, 10, 10)) holds all {} splats of room.ply: nothing would "
                        "be left to fill the hole from",
                        with.size()));
  SplatCloud broken = with;
  broken.log_scales[3 * 7 + 1] = std::nanf("");
  EXPECT_EQ(error_message([&] { fill_splats(broken, box_fill(), cpu_predictor()); }),
            "room.ply: splat 7 has a non-finite scale (nan): the file is damaged");
  FillOptions two = box_fill();
  two.selection = with;
  EXPECT_EQ(error_message([&] { fill_splats(with, two, cpu_predictor()); }),
            "fill: name the region one way: a box, a selection file, or a view and its mask, clicks or box (2 given)");
  FillOptions stroke = box_fill();
  stroke.box.reset();
  stroke.stroke_view = "nope";
  stroke.stroke = Image(8, 8, 1, 1.f);
  EXPECT_EQ(error_message([&] { fill_splats(with, stroke, cpu_predictor()); }),
            "--view nope: no camera of that name (the cameras come from --scene or --cameras)");
}

TEST(FillCli, WritesTheSplatsAndTheReportAndRefusesBadInputWithoutWriting) {
  const std::filesystem::path dir = test::temp_dir("fill-cli");
  write_splats(dir / "room.ply", room(true, false));
  const std::string cli = test::cli_executable().string();
  ASSERT_EQ(test::run_command(cli + " fill " + (dir / "room.ply").string() + " --box 0,0.22,0,0.5,0.44,0.5 --height 64" +
                                  " --views 2 --device cpu --out " + (dir / "filled.spz").string(),
                              dir / "log.txt"),
            0)
      << test::file_bytes(dir / "log.txt");
  EXPECT_GT(read_splats(dir / "filled.spz").size(), 0u);
  const nlohmann::json report = nlohmann::json::parse(test::file_bytes(dir / "filled-fill" / "fill.json"));
  EXPECT_EQ(report["splats"]["input"], room(true, false).size());
  EXPECT_TRUE(std::filesystem::exists(dir / "filled-fill" / "compare.png"));
  EXPECT_EQ(read_camera_json(dir / "filled-fill" / "cameras.json").size(), 2u);

  EXPECT_NE(test::run_command(cli + " fill " + (dir / "room.ply").string() + " --box 9,9,9,1,1,1 --device cpu --out " +
                                  (dir / "nothing.ply").string(),
                              dir / "bad.txt"),
            0);
  EXPECT_NE(test::file_bytes(dir / "bad.txt").find("holds no splat of"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir / "nothing.ply"));
  EXPECT_FALSE(std::filesystem::exists(dir / "nothing-fill"));
}

// `fill --scene` offers every posed view as a camera, the object-free test views too, and the
// stroke's view is the reference by default: a SPIn-NeRF-layout scene's test view with its test
// mask as the stroke (the ground-truth-reference protocol's fill).
TEST(FillCli, AStrokeOnAnObjectFreeTestViewMakesItTheReference) {
  const std::filesystem::path dir = test::temp_dir("fill-test-view");
  test::write_scene(dir / "scene");
  const Scene scene = load_scene(dir / "scene");
  ASSERT_EQ(scene.test_views.at(0).name, "00_test");
  write_splats(dir / "wall.ply",
               splats_from_gaussians(in_scene_frame(gaussians_from_splats(read_splat_ply(dir / "scene" / "truth.ply")),
                                                    scene_normalization(scene))));
  const std::string cli = test::cli_executable().string();
  ASSERT_EQ(test::run_command(cli + " fill " + (dir / "wall.ply").string() + " --scene " + (dir / "scene").string() +
                                  " --view 00_test --mask " + (dir / "scene" / "images" / "test_label" / "00_test.png").string() +
                                  " --reference " + (dir / "scene" / "images" / "00_test.png").string() +
                                  " --views 2 --height 48 --device cpu --out " + (dir / "filled.ply").string(),
                              dir / "log.txt"),
            0)
      << test::file_bytes(dir / "log.txt");
  const nlohmann::json report = nlohmann::json::parse(test::file_bytes(dir / "filled-fill" / "fill.json"));
  EXPECT_EQ(report["cameras"]["reference"], "00_test");
  EXPECT_EQ(report["placement"], "surface");
  EXPECT_GT(report["splats"]["removed"].get<int64_t>(), 0);
}

}  // namespace
}  // namespace ii

namespace ii {
namespace {

TEST(Fill, DeleteOnlyRemovesTheRegionAndAddsNothing) {
  const SplatCloud with = room(true, false);
  FillOptions options = box_fill(2);
  options.fill = false;
  const FillResult r = fill_splats(with, options, cpu_predictor());
  EXPECT_EQ(r.added, 0);
  EXPECT_EQ(r.splats.size(), with.size() - static_cast<size_t>(r.removed));
  EXPECT_EQ(r.splats.size(), room(false, false).size());
}

// The same fill on a GPU (network, renders and refinement on the device) as on the CPU:
// automatic cameras as good; with the capture's cameras the same region, cameras and kept
// splats, about as many new ones, and the same pictures to within float32 rounding of two
// rasterizers. Skipped without a GPU.
TEST(Fill, OnTheGpuAsOnTheCpu) {
  II_REQUIRE_CUDA();
  if (!render_has_cuda()) GTEST_SKIP() << "built without the CUDA rasterizer (no nvcc at configure time)";
  const SplatCloud with = room(true, false);
  const FillOptions options = capture_fill_refined();
  const Predictor gpu_predictor("", torch::kCUDA, Precision::Float32);
  // Automatic cameras (no capture's): cameras that see as much of the region (the room is
  // symmetric, so two cameras may tie and either be taken).
  const FillResult cpu_auto = fill_splats(with, box_fill(2), cpu_predictor());
  const FillResult gpu_auto = fill_splats(with, box_fill(2), gpu_predictor);
  EXPECT_EQ(gpu_auto.removed, cpu_auto.removed);
  ASSERT_EQ(gpu_auto.cameras.visible.size(), cpu_auto.cameras.visible.size());
  for (size_t v = 0; v < cpu_auto.cameras.visible.size(); ++v)
    EXPECT_NEAR(gpu_auto.cameras.visible[v], cpu_auto.cameras.visible[v], 0.01) << "camera " << v;
  EXPECT_GT(gpu_auto.added, 0);
  // The capture's cameras, refined.
  const FillResult cpu = fill_splats(with, options, cpu_predictor());
  const FillResult gpu = fill_splats(with, options, gpu_predictor);
  EXPECT_EQ(gpu.removed, cpu.removed);
  ASSERT_EQ(gpu.cameras.cameras.size(), cpu.cameras.cameras.size());
  for (size_t v = 0; v < cpu.cameras.cameras.size(); ++v) EXPECT_EQ(gpu.cameras.cameras[v].name, cpu.cameras.cameras[v].name);
  EXPECT_NEAR(double(gpu.added), double(cpu.added), 0.02 * double(cpu.added));
  const size_t kept = with.size() - static_cast<size_t>(cpu.removed);
  for (size_t i = 0; i < 3 * kept; ++i) ASSERT_EQ(gpu.splats.means[i], cpu.splats.means[i]);
  ASSERT_EQ(gpu.after.size(), cpu.after.size());
  for (size_t v = 0; v < cpu.after.size(); ++v) {
    const double difference = (image_to_tensor(gpu.after[v]) - image_to_tensor(cpu.after[v])).abs().mean().item<double>();
    EXPECT_LT(difference, 0.01) << "view " << v;
  }
}

// infer writes splats in the scene's frame (the capture's cameras'), --normalized in the network's:
// the same Gaussians, scene = normalized x scale + mean.
TEST(SceneFrame, InferWritesTheScenesFrameAndNormalizedKeepsTheNetworks) {
  II_REQUIRE_SHARED(statue, "data/statue");
  const std::filesystem::path dir = test::temp_dir("scene-frame");
  const std::string base = test::cli_executable().string() + " infer --scene '" + statue.string() +
                           "' --height 64 --device cpu --precision fp32 --threads 1 --out '";
  ASSERT_EQ(test::run_command(base + (dir / "scene").string() + "'", dir / "log.txt"), 0) << test::file_bytes(dir / "log.txt");
  ASSERT_EQ(test::run_command(base + (dir / "norm").string() + "' --normalized", dir / "log.txt"), 0);
  const nlohmann::json run = nlohmann::json::parse(test::file_bytes(dir / "scene" / "run.json"));
  EXPECT_EQ(run["frame"], "scene");
  const double scale = run["normalization"]["scale"];
  const SplatCloud in_scene = read_splats(dir / "scene" / "gaussians.ply");
  const SplatCloud normalized = read_splats(dir / "norm" / "gaussians.ply");
  ASSERT_EQ(in_scene.size(), normalized.size());
  double worst = 0;
  for (size_t i = 0; i < in_scene.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const double expected = normalized.means[3 * i + k] * scale + run["normalization"]["mean"][k].get<double>();
      worst = std::max(worst, std::abs(in_scene.means[3 * i + k] - expected) / scale);
      ASSERT_NEAR(in_scene.log_scales[3 * i + k], normalized.log_scales[3 * i + k] + std::log(scale), 1e-4);
    }
  EXPECT_LT(worst, 1e-5);
  EXPECT_GT(scale, 2);  // the statue's frames differ: the test would not notice otherwise
}

}  // namespace
}  // namespace ii
