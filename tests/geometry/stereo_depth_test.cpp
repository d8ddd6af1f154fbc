// Depth measured from the photos: four views of a textured floor (whose depth is exact) give each
// view's depth from a guide 30 % off, to about a percent where the sweep says it knows it; a
// picture without texture is unknown; bad inputs are refused in words; and a prediction on a
// scene without depth maps puts its Gaussians on that surface when asked, recording it.
#include <gtest/gtest.h>

#include <Eigen/LU>

#include "data/masks.h"
#include "data/scene.h"
#include "model/default_model.h"
#include "predict/predictor.h"
#include "geometry/stereo_depth.h"
#include "geometry/sweep_correlation.h"
#include "geometry/surface_splats.h"
#include "render/rasterizer.h"
#include "synthetic_room.h"
#include "tensor/camera_projection.h"
#include "tensor/image_tensor.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace stereo_depth_test {

struct Views {
  std::vector<Image> photos;
  std::vector<Camera> cameras;
  std::vector<torch::Tensor> depths;  // exact
};

// A synthetic room's four views and its exact depth maps.
Views room_views(const std::string& tag, int side, uint64_t seed) {
  const Scene scene = load_scene(test::synthetic_room(tag, 4, side, seed));
  Views room;
  for (const View& view : scene.views) {
    room.photos.push_back(load_view_image(view));
    room.cameras.push_back(view.camera);
    const Image depth = *load_view_depth(scene, view);
    room.depths.push_back(
        torch::from_blob(const_cast<float*>(depth.pixels.data()), {depth.height, depth.width}, torch::kFloat32)
            .clone());
  }
  return room;
}

// A camera of `side` pixels square looking along the world's -z from (x, y, 0), unturned.
Camera camera_at(int side, double x, double y) {
  Camera camera;
  camera.K = Intrinsics::from_fov(side, side, 1.0, 1.0);
  camera.c2w(0, 3) = x;
  camera.c2w(1, 3) = y;
  return camera;
}

// Camera z of a slanted floor (2.5 units ahead at the height y = 0, nearer below) seen by a camera
// from camera_at: the ray through each pixel centre meets z = -(2.5 - 0.5 y).
torch::Tensor floor_depth(const Camera& camera) {
  const Intrinsics& K = camera.K;
  const torch::Tensor b = (torch::arange(K.height, torch::kFloat32) + 0.5f - K.cy) / K.fy;  // down per unit z
  const double y = camera.c2w(1, 3);
  return ((2.5 - 0.5 * y) / (1 - 0.5 * b)).view({K.height, 1}).expand({K.height, K.width}).contiguous();
}

// Four views of that floor painted with seeded noise (blobs of about two pixels), rendered from
// flat splats that tile it as a wider camera at the origin sees it.
Views textured_floor(int side) {
  torch::manual_seed(35);
  const Camera wide = [&] {
    Camera c = camera_at(side, 0, 0);
    c.K.width = c.K.height = 2 * side;
    c.K.cx = c.K.cy = side;
    return c;
  }();
  const torch::Tensor noise =
      torch::upsample_bilinear2d(torch::rand({1, 3, side, side}), {2 * side, 2 * side}, false);
  const GaussianSet floor = surface_gaussians(wide, floor_depth(wide), torch::ones({2 * side, 2 * side}, torch::kBool),
                                              tensor_to_image(noise), 0.99f, 0.7);
  Views views;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{0, 0}, {0.15, 0}, {0, 0.12}, {-0.12, -0.05}}) {
    RenderCamera camera;
    camera.camera = camera_at(side, x, y);
    views.photos.push_back(image_from_hwc(render(floor, camera).rgb));
    views.cameras.push_back(camera.camera);
    views.depths.push_back(floor_depth(camera.camera));
  }
  return views;
}

// The fraction of a measured depth's pixels that are known.
double known_fraction(const torch::Tensor& measured) {
  return measured.gt(0).to(torch::kFloat32).mean().item<double>();
}

// |log| of the measured depth's ratio to the truth where it is known.
torch::Tensor log_error(const torch::Tensor& measured, const torch::Tensor& truth) {
  const torch::Tensor known = measured.gt(0);
  return (measured.index({known}) / truth.index({known})).log().abs();
}

TEST(StereoDepth, FindsATexturedFloorsDepthFromAGuideThirtyPercentOff) {
  const Views floor = textured_floor(96);
  std::vector<torch::Tensor> guides;
  for (const torch::Tensor& depth : floor.depths) guides.push_back(depth * 1.3);
  StereoOptions options;
  options.rows = 96;
  const std::vector<torch::Tensor> measured = stereo_depth(floor.photos, floor.cameras, guides, options);
  ASSERT_EQ(measured.size(), 4u);
  for (size_t v = 0; v < 4; ++v) {
    EXPECT_GT(known_fraction(measured[v]), 0.6) << "view " << v;
    const torch::Tensor error = log_error(measured[v], floor.depths[v]);
    EXPECT_LT(error.median().item<double>(), 0.01) << "view " << v;
    EXPECT_LT(torch::quantile(error, 0.9).item<double>(), 0.03) << "view " << v;
  }
}

// The correlation written as LibTorch's operations (zero-padded window sums, grid_sampler): what
// sweep_correlation must give, as it did before it was one pass.
torch::Tensor window_mean_by_operations(const torch::Tensor& x, int window) {  // x (B, C, H, W)
  auto sums = [&](const torch::Tensor& t, int64_t dim) {
    const int64_t half = window / 2;
    const std::vector<int64_t> pad =
        dim == 3 ? std::vector<int64_t>{half + 1, half} : std::vector<int64_t>{0, 0, half + 1, half};
    const torch::Tensor running = torch::constant_pad_nd(t, pad, 0).cumsum(dim);
    return running.narrow(dim, window, t.size(dim)) - running.narrow(dim, 0, t.size(dim));
  };
  const torch::Tensor ones = torch::ones({1, 1, x.size(2), x.size(3)});
  return sums(sums(x, 3), 2) / sums(sums(ones, 3), 2);
}

torch::Tensor correlation_by_operations(const torch::Tensor& reference, const Camera& reference_camera,
                                        const torch::Tensor& source, const Camera& source_camera,
                                        const torch::Tensor& depths, int window) {
  const int64_t h = reference.size(0), w = reference.size(1), D = depths.size(0);
  const torch::Tensor ref = reference.view({1, 1, h, w});
  const torch::Tensor ref_mean = window_mean_by_operations(ref, window);
  const torch::Tensor ref_deviation =
      (window_mean_by_operations(ref * ref, window) - ref_mean * ref_mean).clamp_min(0).sqrt();
  const Eigen::Matrix4d to_source = source_camera.w2c_opencv() * reference_camera.w2c_opencv().inverse();
  const auto [R, t] = rotation_and_translation(to_source, torch::TensorOptions(torch::kFloat32));
  const Intrinsics& RK = reference_camera.K;
  const torch::Tensor x = (torch::arange(w, torch::kFloat32) + 0.5f - RK.cx) / RK.fx;
  const torch::Tensor y = (torch::arange(h, torch::kFloat32) + 0.5f - RK.cy) / RK.fy;
  const std::vector<torch::Tensor> grid_xy = torch::meshgrid({y, x}, "ij");
  const torch::Tensor turned =
      torch::stack({grid_xy[1].flatten(), grid_xy[0].flatten(), torch::ones({h * w})}, 1).matmul(R.t());
  auto axis = [&](int64_t i) { return depths * turned.select(1, i).unsqueeze(0) + t[i]; };
  const torch::Tensor z = axis(2);
  const torch::Tensor reciprocal = z.clamp_min(1e-6).reciprocal();
  const Intrinsics& K = source_camera.K;
  const torch::Tensor gx = axis(0) * reciprocal * (2.0 * K.fx / K.width) + (2.0 * K.cx / K.width - 1);
  const torch::Tensor gy = axis(1) * reciprocal * (2.0 * K.fy / K.height) + (2.0 * K.cy / K.height - 1);
  const torch::Tensor inside = z.gt(1e-6).logical_and(gx.abs().le(1)).logical_and(gy.abs().le(1)).view({D, 1, h, w});
  const torch::Tensor warped =
      torch::grid_sampler(source.view({1, 1, K.height, K.width}).expand({D, 1, K.height, K.width}),
                          torch::stack({gx, gy}, 2).view({D, h, w, 2}), 0, 0, false);
  const torch::Tensor means = window_mean_by_operations(torch::cat({warped, warped * warped, warped * ref}, 1), window);
  const torch::Tensor mean = means.narrow(1, 0, 1);
  const torch::Tensor deviation = (means.narrow(1, 1, 1) - mean * mean).clamp_min(0).sqrt();
  const torch::Tensor ncc = (means.narrow(1, 2, 1) - mean * ref_mean) / (deviation * ref_deviation + 1e-4f);
  return torch::where(inside, ncc, torch::full({}, -1.0f)).squeeze(1);
}

// (ctest runs it again on the baseline loop: geometry.StereoOnTheBaseline.)
TEST(StereoDepth, TheSweepsCorrelationIsWhatLibTorchsOperationsGive) {
  const Views floor = textured_floor(48);
  // 45 x 47 pixels: not a whole number of 8-pixel vectors (the vectorised warp's last pixels too).
  const Camera reference = floor.cameras[0].resized(45, 47);
  const torch::Tensor reference_grey = torch::adaptive_avg_pool2d(
      image_to_tensor(floor.photos[0]).narrow(1, 0, 3).mean(1, true), {47, 45})[0][0];
  torch::manual_seed(36);
  for (size_t s = 1; s < 4; ++s) {
    // A smaller source camera too: the two pictures need not be the same size.
    const Camera source = s == 3 ? floor.cameras[s].resized(32, 40) : floor.cameras[s];
    torch::Tensor source_grey = image_to_tensor(floor.photos[s]).narrow(1, 0, 3).mean(1, true);
    source_grey = torch::adaptive_avg_pool2d(source_grey, {source.K.height, source.K.width})[0][0];
    // Depths from in front of the camera (behind the source too) to far off the floor.
    const torch::Tensor depths =
        torch::logspace(-2, 1, 9).unsqueeze(1) * (1 + 0.1 * torch::rand({1, 45 * 47}));
    const torch::Tensor fused = sweep_correlation(reference_grey, reference, source_grey, source, depths, 5);
    const torch::Tensor expected = correlation_by_operations(reference_grey, reference, source_grey, source, depths, 5);
    ASSERT_EQ(fused.sizes(), expected.sizes());
    const torch::Tensor outside = expected.eq(-1);
    EXPECT_GT(outside.sum().item<int64_t>(), 0) << "some points outside the source";
    EXPECT_LT(outside.sum().item<int64_t>(), outside.numel()) << "some inside";
    EXPECT_EQ(fused.eq(-1).ne(outside).sum().item<int64_t>(), 0) << "source " << s;
    EXPECT_LT((fused - expected).abs().max().item<double>(), 1e-3) << "source " << s;
  }
  EXPECT_EQ(test::error_message([&] {
              sweep_correlation(reference_grey, reference, reference_grey, reference, torch::ones({2, 7}), 5);
            }),
            "the sweep's pictures and depths do not match their cameras' sizes");
}

TEST(StereoDepth, AFlatPictureIsUnknown) {
  Views room = room_views("stereo-flat", 64, 32);
  for (Image& photo : room.photos) std::fill(photo.pixels.begin(), photo.pixels.end(), 0.5f);
  for (const torch::Tensor& measured : stereo_depth(room.photos, room.cameras, room.depths))
    EXPECT_EQ(known_fraction(measured), 0.0);
}

TEST(StereoDepth, RefusesWhatItCannotMatch) {
  const Views room = room_views("stereo-refuses", 32, 33);
  const std::string needs = "stereo depth needs two or more photos with a camera and a guiding depth each";
  EXPECT_EQ(test::error_message([&] { stereo_depth({room.photos[0]}, {room.cameras[0]}, {room.depths[0]}); }), needs);
  EXPECT_EQ(test::error_message([&] { stereo_depth(room.photos, room.cameras, {room.depths[0]}); }), needs);
  StereoOptions narrow;
  narrow.spread = 1;
  EXPECT_EQ(test::error_message([&] { stereo_depth(room.photos, room.cameras, room.depths, narrow); }),
            "stereo depth needs a spread above 1");
}

#define II_REQUIRE_DEFAULT_MODEL() \
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model"

TEST(StereoDepth, APredictionWithoutDepthMapsLiesOnTheSurfaceThePhotosMeasure) {
  II_REQUIRE_DEFAULT_MODEL();
  const std::filesystem::path dir = test::synthetic_room("stereo-predict", 4, 128, 34);
  std::filesystem::remove_all(dir / "depth");  // a capture without a depth camera
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions options;
  options.preprocess.height = 128;
  ASSERT_TRUE(options.geometry.measured_surface.from_photos);  // the default
  const Prediction with = predictor.predict(scene, options);
  const nlohmann::json record = with.describe_geometry()["measured_surface"];
  EXPECT_EQ(record["source"], "the photos (stereo)");
  ASSERT_EQ(record["views"].size(), 4u);
  ASSERT_EQ(record["known"].size(), 4u);
  // The rooms' marble is faintly textured: a few percent of each view is known.
  for (const auto& known : record["known"]) EXPECT_GT(known.get<double>(), 0.01);
  EXPECT_GT(record["gaussians"].get<int64_t>(), 500);
  // Off: the network's Gaussians, nothing recorded as moved.
  options.geometry.measured_surface.from_photos = false;
  const nlohmann::json off = predictor.predict(scene, options).describe_geometry()["measured_surface"];
  EXPECT_EQ(off["source"], "");
  EXPECT_EQ(off["gaussians"], 0);
}

}  // namespace stereo_depth_test
}  // namespace
}  // namespace ii
