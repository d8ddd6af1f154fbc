// Training samples: clip layout, exact intrinsics after resize + crop, masks per stage and
// mode, determinism per (seed, index), the prefetching stream, and the shared scenes.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "data/scene.h"
#include "io/npy.h"
#include "synthetic_room.h"
#include "train/sample.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

// A forward-facing LLFF scene in a temporary folder: cameras (identity rotation) spread along
// x with a little y wobble, 96x64 photos of a dark gradient with a white disc (radius 3 px)
// where the marker point projects. Optional: object masks (radius 5 px around the disc),
// clean/ images without the disc, depth/ maps of the marker's depth.
const Eigen::Vector3d kMarker(0.2, -0.1, -5.0);
constexpr int kW = 96, kH = 64;
constexpr double kFocal = 60;

Eigen::Vector3d camera_centre(int k, int n) { return {-1.0 + 2.0 * k / (n - 1), 0.15 * std::sin(k), 0.0}; }

struct SceneFiles {
  bool masks = true, clean = false, depth = false;
  static SceneFiles with(bool masks, bool clean, bool depth) {
    SceneFiles f;
    f.masks = masks, f.clean = clean, f.depth = depth;
    return f;
  }
};

fs::path write_scene(int n, SceneFiles files = {}) {
  const fs::path dir = test::temp_dir("sample-scene");
  fs::create_directories(dir / "images" / "label");
  if (files.clean) fs::create_directories(dir / "clean");
  if (files.depth) fs::create_directories(dir / "depth");
  std::vector<double> rows;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d c = camera_centre(k, n);
    // LLFF columns (down, right, back) of an OpenGL identity rotation, then [t | (H, W, f)].
    const double m[15] = {0, 1, 0, c.x(), kH, -1, 0, 0, c.y(), kW, 0, 0, 1, c.z(), kFocal};
    rows.insert(rows.end(), m, m + 15);
    rows.push_back(2.0);
    rows.push_back(20.0);
    const double u = kFocal * (kMarker.x() - c.x()) / -kMarker.z() + kW / 2.0;
    const double v = kFocal * -(kMarker.y() - c.y()) / -kMarker.z() + kH / 2.0;
    Image photo(kW, kH, 3), clean(kW, kH, 3), mask(kW, kH, 1);
    for (int i = 0; i < kH; ++i)
      for (int j = 0; j < kW; ++j) {
        const float bg[3] = {0.1f + 0.2f * j / kW, 0.2f, 0.1f + 0.2f * i / kH};
        const double r = std::hypot(j + 0.5 - u, i + 0.5 - v);
        for (int ch = 0; ch < 3; ++ch) {
          clean.at(i, j, ch) = bg[ch];
          photo.at(i, j, ch) = r <= 3.0 ? 1.f : bg[ch];
        }
        mask.at(i, j) = r <= 5.0 ? 1.f : 0.f;
      }
    const std::string name = fmt::format("frame{:02d}", k);
    write_png(dir / "images" / (name + ".png"), photo);
    if (files.masks) write_png(dir / "images" / "label" / (name + ".png"), mask);
    if (files.clean) write_png(dir / "clean" / (name + ".png"), clean);
    if (files.depth)
      write_npy(dir / "depth" / (name + ".npy"), std::vector<double>(kW * kH, -kMarker.z()), {kH, kW});
  }
  write_npy(dir / "poses_bounds.npy", rows, {n, 17});
  if (!files.masks) fs::remove(dir / "images" / "label");
  return dir;
}

SamplerOptions small_options(TrainStage stage = TrainStage::Inpaint) {
  SamplerOptions o;
  o.stage = stage;
  o.height = 40;
  o.width = 48;
  return o;
}

// Value in [-1,1] of channel 0 at the pixel where the marker projects, or nullopt when it
// falls outside the image.
std::optional<float> marker_value(const torch::Tensor& image, const Camera& cam, const PoseNormalization& norm,
                                  int dx = 0) {
  const Eigen::Vector3d X = norm.apply(kMarker);
  const Eigen::Matrix4d w2c = cam.w2c_opencv();
  const Eigen::Vector3d Y = w2c.block<3, 3>(0, 0) * X + w2c.block<3, 1>(0, 3);
  const int col = static_cast<int>(std::floor(cam.K.fx * Y.x() / Y.z() + cam.K.cx)) + dx;
  const int row = static_cast<int>(std::floor(cam.K.fy * Y.y() / Y.z() + cam.K.cy));
  if (col < 0 || row < 0 || col >= cam.K.width || row >= cam.K.height) return std::nullopt;
  return image[0][row][col].item<float>();
}

PoseNormalization clip_normalization(const Scene& scene, const SampleInfo& info) {
  std::vector<Camera> cams;
  for (int v : info.clip) cams.push_back(scene.views[v].camera);
  return fit_pose_normalization(cams);
}

TEST(Sample, ClipLayoutFollowsTheOfficialRecipe) {
  const Scene scene = load_scene(write_scene(18));
  for (uint64_t s = 0; s < 8; ++s) {
    SampleInfo info;
    const TrainingSample sample = make_scene_sample(scene, small_options(), s, {}, &info);
    ASSERT_EQ(info.clip.size(), 15u);
    const int start = info.clip.front();
    EXPECT_LE(start, 3);
    for (int k = 0; k < 15; ++k) EXPECT_EQ(info.clip[k], start + k);
    const int ref = info.inputs[0] - start;
    ASSERT_TRUE(ref == 4 || ref == 9) << ref;
    std::vector<int> rest = {0, 4, 9, 14};
    rest.erase(std::find(rest.begin(), rest.end(), ref));
    for (int k = 1; k < 4; ++k) EXPECT_EQ(info.inputs[k] - start, rest[k - 1]);
    ASSERT_EQ(info.targets.size(), 8u);
    std::set<int> targets(info.targets.begin(), info.targets.end());
    EXPECT_EQ(targets.size(), 8u);  // 11 candidates: no repeats
    for (int t : info.targets) {
      EXPECT_TRUE(std::find(info.inputs.begin(), info.inputs.end(), t) == info.inputs.end());
      EXPECT_GE(t, start);
      EXPECT_LT(t, start + 15);
    }
    EXPECT_EQ(sample.input.images.sizes(), (std::vector<int64_t>{4, 4, 40, 48}));
    EXPECT_EQ(sample.target_images.sizes(), (std::vector<int64_t>{8, 3, 40, 48}));
    EXPECT_EQ(sample.input.names[0], scene.views[info.inputs[0]].name);
    EXPECT_EQ(sample.target_cameras.size(), 8u);
    // Poses normalised over the clip: all 15 centres in [-1, 1], one coordinate at +-1.
    EXPECT_LE(sample.input.rays_o.abs().max().item<float>(), 1.f + 1e-6f);
  }
}

TEST(Sample, ShortScenesUseAllViewsSpreadEvenly) {
  const Scene scene = load_scene(write_scene(8));
  SampleInfo info;
  make_scene_sample(scene, small_options(), 3, {}, &info);
  EXPECT_EQ(info.clip, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7}));
  // Positions floor(k * 7 / 3) = 0, 2, 4, 7; reference 2 or 4 first.
  std::set<int> inputs(info.inputs.begin(), info.inputs.end());
  EXPECT_EQ(inputs, (std::set<int>{0, 2, 4, 7}));
  EXPECT_TRUE(info.inputs[0] == 2 || info.inputs[0] == 4);
  // Four candidates {1, 3, 5, 6} fill eight targets, each twice.
  ASSERT_EQ(info.targets.size(), 8u);
  for (int c : {1, 3, 5, 6}) EXPECT_EQ(std::count(info.targets.begin(), info.targets.end(), c), 2);

  const fs::path tiny = write_scene(4);
  const Scene four = load_scene(tiny);
  EXPECT_EQ(test::error_message([&] { make_scene_sample(four, small_options(), 0); }),
            "scene " + tiny.string() + ": 4 views, training needs at least 5 (4 inputs and one supervision view)");
  SamplerOptions bad = small_options();
  bad.clip_length = 4;
  EXPECT_EQ(test::error_message([&] { make_scene_sample(scene, bad, 0); }),
            "sampler: clip_length 4 leaves no supervision frame besides 4 inputs");
}

TEST(Sample, IntrinsicsAreExactAfterResizeAndCrop) {
  const Scene scene = load_scene(write_scene(18));
  int checked = 0;
  std::set<int> crops;
  for (uint64_t s = 0; s < 6; ++s) {
    SampleInfo info;
    const TrainingSample sample = make_scene_sample(scene, small_options(TrainStage::Reconstruct), s, {}, &info);
    crops.insert(info.crop_x);
    EXPECT_EQ(info.resized_width, 60);  // 96x64 -> 60x40 covers 48x40
    EXPECT_EQ(info.resized_height, 40);
    const PoseNormalization norm = clip_normalization(scene, info);
    auto check = [&](const torch::Tensor& image, const Camera& cam) {
      EXPECT_DOUBLE_EQ(cam.K.fx, kFocal * 40 / 64);
      EXPECT_DOUBLE_EQ(cam.K.cx, kW / 2.0 * 40 / 64 - info.crop_x);
      EXPECT_DOUBLE_EQ(cam.K.cy, 20.0);
      const auto centre = marker_value(image, cam, norm);
      const auto beside = marker_value(image, cam, norm, 5);
      if (!centre || !beside) return;
      EXPECT_GT(*centre, 0.9f);   // the white disc
      EXPECT_LT(*beside, -0.3f);  // background
      ++checked;
    };
    for (int k = 0; k < 4; ++k) check(sample.input.images[k], sample.input.view_cameras[k]);
    for (int m = 0; m < 8; ++m) check(sample.target_images[m], sample.target_cameras[m]);
    // Rays start at the normalised camera centres.
    EXPECT_NEAR(sample.input.rays_o[1][0][0][0].item<float>(), sample.input.view_cameras[1].center().x(), 1e-6);
  }
  EXPECT_GT(checked, 50);
  EXPECT_GT(crops.size(), 1u);  // the crop moves
}

TEST(Sample, ReferenceFirstUnmaskedAndMaskChannelRulesPerStage) {
  const Scene scene = load_scene(write_scene(18));
  for (const std::array<double, 3>& mix : {std::array<double, 3>{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}) {
    SamplerOptions inpaint = small_options();
    inpaint.mask_mix = mix;
    SampleInfo info, plain_info;
    const TrainingSample masked = make_scene_sample(scene, inpaint, 17, {}, &info);
    const TrainingSample plain = make_scene_sample(scene, small_options(TrainStage::Reconstruct), 17, {}, &plain_info);
    // Same random stream: same clip and crop in both stages.
    EXPECT_EQ(info.inputs, plain_info.inputs);
    EXPECT_EQ(info.crop_x, plain_info.crop_x);
    EXPECT_FALSE(plain_info.mask_mode.has_value());
    EXPECT_EQ(plain.input.images.select(1, 3).abs().sum().item<float>(), 0.f);  // stage 1: no masks

    const auto& images = masked.input.images;
    EXPECT_EQ(images[0][3].abs().sum().item<float>(), 0.f);
    EXPECT_TRUE(torch::equal(images[0].narrow(0, 0, 3), plain.input.images[0].narrow(0, 0, 3)));
    for (int k = 1; k < 4; ++k) {
      const auto mask = images[k][3];
      EXPECT_TRUE(torch::equal(mask, (mask > 0.5).to(torch::kFloat32)));  // binary
      EXPECT_GT(mask.sum().item<float>(), 0.f) << mask_mode_name(*info.mask_mode);
      EXPECT_TRUE(torch::equal(images[k].narrow(0, 0, 3), plain.input.images[k].narrow(0, 0, 3) * (1.0 - mask)));
    }
    ASSERT_TRUE(info.mask_mode.has_value());
    if (mix[1] > 0) {
      EXPECT_EQ(*info.mask_mode, MaskMode::Random);
      EXPECT_TRUE(torch::equal(images[1][3], images[2][3]));  // one mask for every view
      EXPECT_TRUE(torch::equal(images[1][3], images[3][3]));
    }
    if (mix[0] > 0) {
      EXPECT_EQ(*info.mask_mode, MaskMode::Instance);
      // The dilated object mask covers the disc.
      const PoseNormalization norm = clip_normalization(scene, info);
      for (int k = 1; k < 4; ++k)
        if (auto v = marker_value(images[k].narrow(0, 3, 1), masked.input.view_cameras[k], norm)) {
          EXPECT_EQ(*v, 1.f);
        }
    }
    if (mix[2] > 0) {
      EXPECT_EQ(*info.mask_mode, MaskMode::Consistent3D);
      EXPECT_EQ(info.depth_source, "plane");
    }
    // Targets are the photos in both stages (no clean/ folder).
    EXPECT_TRUE(torch::equal(masked.target_images, plain.target_images));
  }
}

TEST(Sample, DepthSourcesForConsistentMasks) {
  SamplerOptions o = small_options();
  o.mask_mix = {0, 0, 1};
  const Scene with_depth = load_scene(write_scene(16, SceneFiles::with(true, false, true)));
  SampleInfo info;
  make_scene_sample(with_depth, o, 1, {}, &info);
  EXPECT_EQ(info.depth_source, "depth/");

  const Scene scene = load_scene(write_scene(16));
  int calls = 0;
  const DepthProvider provider = [&](const Scene&, const View& view) -> std::optional<Image> {
    ++calls;
    return Image(view.camera.K.width, view.camera.K.height, 1, 5.f);
  };
  const TrainingSample injected = make_scene_sample(scene, o, 1, provider, &info);
  EXPECT_EQ(info.depth_source, "injected");
  EXPECT_EQ(calls, 1);
  // The injected plane is the scene's depth/ content: identical masks.
  const TrainingSample from_folder = make_scene_sample(with_depth, o, 1);
  EXPECT_TRUE(torch::equal(injected.input.images.select(1, 3), from_folder.input.images.select(1, 3)));

  const DepthProvider wrong = [](const Scene&, const View&) -> std::optional<Image> { return Image(3, 3, 1, 1.f); };
  EXPECT_EQ(test::error_message([&] { make_scene_sample(scene, o, 1, wrong); }).rfind("view frame", 0), 0u);
}

TEST(Sample, InputDepthsFollowTheImagesTheInputsShouldShow) {
  const fs::path dir = write_scene(16, SceneFiles::with(true, true, true));
  SamplerOptions o = small_options();
  // Without depth_clean/ a stage-2 sample of a clean scene has no depth it could trust.
  EXPECT_FALSE(make_scene_sample(load_scene(dir), o, 3).input_depths.defined());
  fs::create_directories(dir / "depth_clean");
  for (const auto& entry : fs::directory_iterator(dir / "depth"))
    write_npy(dir / "depth_clean" / entry.path().filename(), std::vector<double>(kW * kH, 7.0), {kH, kW});
  const Scene scene = load_scene(dir);
  for (TrainStage stage : {TrainStage::Inpaint, TrainStage::Reconstruct}) {
    SampleInfo info;
    const TrainingSample sample = make_scene_sample(scene, small_options(stage), 3, {}, &info);
    const bool clean = stage == TrainStage::Inpaint;
    EXPECT_EQ(info.input_depth_folder, clean ? "depth_clean" : "depth");
    ASSERT_TRUE(sample.input_depths.defined());
    EXPECT_EQ(sample.input_depths.sizes(), (std::vector<int64_t>{4, 1, o.height, o.width}));
    // In the normalised units of the sample's cameras.
    const double expected = (clean ? 7.0 : -kMarker.z()) / clip_normalization(scene, info).scale;
    EXPECT_NEAR(sample.input_depths.min().item<double>(), expected, 1e-5);
    EXPECT_NEAR(sample.input_depths.max().item<double>(), expected, 1e-5);
  }
  // Scenes without depth maps: none.
  EXPECT_FALSE(make_scene_sample(load_scene(write_scene(16)), o, 3).input_depths.defined());
}

// A scene without depth maps, with depth_from_photos: each input's depth at points triangulated
// from its photos, sparse, where the same room's depth maps have it.
TEST(Sample, WithoutDepthMapsTheInputsDepthComesFromThePhotosPoints) {
  const Scene with_maps = load_scene(test::synthetic_room("sample-depth-maps", 8, 256, 8));
  const fs::path bare = test::synthetic_room("sample-depth-photos", 8, 256, 8);
  fs::remove_all(bare / "depth");
  fs::remove_all(bare / "depth_clean");
  const Scene scene = load_scene(bare);
  SamplerOptions o = small_options(TrainStage::Reconstruct);
  o.width = o.height = 128;
  EXPECT_FALSE(make_scene_sample(scene, o, 5).input_depths.defined()) << "only when asked";
  o.depth_from_photos = true;
  SampleInfo info, dense_info;
  const TrainingSample sparse = make_scene_sample(scene, o, 5, {}, &info);
  const TrainingSample dense = make_scene_sample(with_maps, o, 5, {}, &dense_info);
  EXPECT_EQ(info.input_depth_folder, "photos");
  EXPECT_EQ(dense_info.input_depth_folder, "depth");
  ASSERT_EQ(info.inputs, dense_info.inputs);
  ASSERT_TRUE(sparse.input_depths.defined());
  ASSERT_EQ(sparse.input_depths.sizes(), dense.input_depths.sizes());
  const torch::Tensor known = sparse.input_depths > 0;
  const int64_t count = known.sum().item<int64_t>();
  EXPECT_GT(count, 4 * 20) << "points in each view";
  EXPECT_LT(count, sparse.input_depths.numel() / 10) << "sparse";
  const torch::Tensor error = (sparse.input_depths.index({known}) / dense.input_depths.index({known})).log().abs();
  EXPECT_LT(error.median().item<double>(), 0.03);
}

TEST(Sample, CleanFolderGivesTheReferenceAndTargets) {
  const Scene scene = load_scene(write_scene(16, SceneFiles::with(true, true, false)));
  SamplerOptions o = small_options();
  o.mask_mix = {0, 1, 0};
  int checked = 0;
  for (uint64_t s = 0; s < 4; ++s) {
    SampleInfo info;
    const TrainingSample sample = make_scene_sample(scene, o, s, {}, &info);
    EXPECT_TRUE(info.clean_reference);
    const PoseNormalization norm = clip_normalization(scene, info);
    if (auto v = marker_value(sample.input.images[0], sample.input.view_cameras[0], norm)) {
      EXPECT_LT(*v, -0.3f);  // the object is gone from the reference
      ++checked;
    }
    for (int m = 0; m < 8; ++m)
      if (auto v = marker_value(sample.target_images[m], sample.target_cameras[m], norm)) {
        EXPECT_LT(*v, -0.3f);
      }
    for (int k = 1; k < 4; ++k)  // the object is always hidden in the other inputs
      if (auto v = marker_value(sample.input.images[k].narrow(0, 3, 1), sample.input.view_cameras[k], norm)) {
        EXPECT_EQ(*v, 1.f);
        EXPECT_EQ(*marker_value(sample.input.images[k], sample.input.view_cameras[k], norm), 0.f);
      }
  }
  EXPECT_GT(checked, 0);
  // Stage 1 reconstructs the photos as they are.
  SampleInfo info;
  const TrainingSample plain = make_scene_sample(scene, small_options(TrainStage::Reconstruct), 0, {}, &info);
  EXPECT_FALSE(info.clean_reference);
  if (auto v = marker_value(plain.input.images[0], plain.input.view_cameras[0], clip_normalization(scene, info))) {
    EXPECT_GT(*v, 0.9f);
  }
}

TEST(Sample, DeterministicPerSeedAndIndex) {
  const std::vector<Scene> scenes = {load_scene(write_scene(18)), load_scene(write_scene(9))};
  const SamplerOptions o = small_options();
  for (int64_t index : {0, 3, 11}) {
    set_sample_image_cache_limit(0);  // decoded afresh ...
    const TrainingSample a = make_sample(scenes, o, 7, index);
    set_sample_image_cache_limit(size_t(1) << 30);  // ... or from the cache: same data
    make_sample(scenes, o, 7, index);
    const TrainingSample b = make_sample(scenes, o, 7, index);
    EXPECT_TRUE(torch::equal(a.input.images, b.input.images));
    EXPECT_TRUE(torch::equal(a.input.plucker, b.input.plucker));
    EXPECT_TRUE(torch::equal(a.input.cameras, b.input.cameras));
    EXPECT_TRUE(torch::equal(a.target_images, b.target_images));
    for (size_t m = 0; m < a.target_cameras.size(); ++m)
      EXPECT_EQ(a.target_cameras[m].c2w, b.target_cameras[m].c2w);
    EXPECT_EQ(a.scene, b.scene);
  }
  EXPECT_FALSE(torch::equal(make_sample(scenes, o, 7, 0).input.images, make_sample(scenes, o, 8, 0).input.images));
  // Each run of len(scenes) indices visits every scene once.
  for (int64_t epoch = 0; epoch < 4; ++epoch) {
    std::set<size_t> seen;
    for (int64_t i = 0; i < 5; ++i) seen.insert(scene_for_index(5, 99, epoch * 5 + i));
    EXPECT_EQ(seen.size(), 5u);
  }
  EXPECT_EQ(test::error_message([&] { make_sample(scenes, o, 7, -1); }), "sample index must be non-negative, got -1");
}

TEST(Sample, StreamPrefetchesInOrder) {
  const std::vector<Scene> scenes = {load_scene(write_scene(18)), load_scene(write_scene(9))};
  SamplerOptions o = small_options();
  o.num_targets = 2;
  for (int workers : {0, 3}) {
    // Rank 1 of 2 from global index 4: indices 5, 7, 9, ...
    SampleStream stream(scenes, o, 42, 4, 1, 2, workers, 2);
    for (int64_t expected = 5; expected < 17; expected += 2) {
      EXPECT_EQ(stream.next_index(), expected);
      const TrainingSample got = stream.next();
      const TrainingSample want = make_sample(scenes, o, 42, expected);
      EXPECT_TRUE(torch::equal(got.input.images, want.input.images)) << expected;
      EXPECT_TRUE(torch::equal(got.target_images, want.target_images)) << expected;
    }
    EXPECT_EQ(stream.next_index(), 17);
  }
  EXPECT_EQ(test::error_message([&] { SampleStream(scenes, o, 1, 0, 2, 2); }),
            "sample stream: rank 2 is outside a world of size 2");
  EXPECT_EQ(test::error_message([&] { SampleStream({}, o, 1, 0); }), "sample stream: no training scenes");
}

// A size cycle: every sample of a step (the global batch: step_samples indices) takes that step's
// size, in turn, with the intrinsics of that size; ranks of a world agree; a size too small is refused.
TEST(Sample, ASizeCycleGivesEachStepOneSizeInTurn) {
  const std::vector<Scene> scenes = {load_scene(write_scene(18)), load_scene(write_scene(9))};
  SamplerOptions o = small_options();
  o.num_targets = 2;
  o.size_cycle = {{32, 32}, {32, 32}, {48, 40}};
  o.step_samples = 4;  // batch 2 on 2 ranks
  auto size_of = [](const TrainingSample& s) { return std::make_pair(int(s.input.images.size(3)), int(s.input.images.size(2))); };
  for (int rank : {0, 1}) {
    SampleStream stream(scenes, o, 42, 0, rank, 2, 2, 2);
    for (int step = 0; step < 6; ++step)
      for (int j = 0; j < 2; ++j) {
        const TrainingSample s = stream.next();
        const std::pair<int, int> want = step % 3 == 2 ? std::make_pair(48, 40) : std::make_pair(32, 32);
        EXPECT_EQ(size_of(s), want) << "rank " << rank << " step " << step;
        EXPECT_EQ(s.target_images.size(3), want.first);
        EXPECT_EQ(s.target_cameras[0].K.width, want.first);
        EXPECT_EQ(s.target_cameras[0].K.height, want.second);
      }
  }
  EXPECT_EQ(options_for_index(o, 9).width, 48);
  EXPECT_EQ(options_for_index(o, 12).width, 32);
  o.size_cycle.emplace_back(4, 32);
  EXPECT_EQ(test::error_message([&] { check_sampler_options(o); }),
            "sampler: working size 4x32 of the size cycle is too small");
}

TEST(Sample, StreamWorkerErrorsSurfaceAsExceptions) {
  const fs::path dir = write_scene(8, SceneFiles::with(false, false, false));
  const std::vector<Scene> scenes = {load_scene(dir)};
  for (int k = 0; k < 8; ++k) fs::remove(dir / "images" / fmt::format("frame{:02d}.png", k));
  set_sample_image_cache_limit(0);
  {
    SampleStream stream(scenes, small_options(), 3, 0, 0, 1, 2, 3);
    for (int attempt = 0; attempt < 3; ++attempt) {
      const std::string message = test::error_message([&] { stream.next(); });
      EXPECT_NE(message.find("frame0"), std::string::npos) << message;
    }
    EXPECT_EQ(stream.next_index(), 3);  // failed indices are consumed
  }  // the destructor joins the workers without hanging
  set_sample_image_cache_limit(size_t(1) << 30);
}

TEST(Sample, SharedFernAndStatue) {
  II_REQUIRE_SHARED(fern_dir, "data/fern");
  II_REQUIRE_SHARED(statue_dir, "data/statue");
  const Scene fern = load_scene(fern_dir), statue = load_scene(statue_dir);
  SamplerOptions o;
  o.height = o.width = 64;
  for (uint64_t s = 0; s < 4; ++s) {
    SampleInfo info;
    const TrainingSample sample = make_scene_sample(fern, o, s, {}, &info);
    EXPECT_NE(*info.mask_mode, MaskMode::Instance);  // fern has no object masks
    EXPECT_EQ(sample.input.images.sizes(), (std::vector<int64_t>{4, 4, 64, 64}));
    EXPECT_EQ(sample.target_images.sizes(), (std::vector<int64_t>{8, 3, 64, 64}));
    EXPECT_EQ(sample.scene, "fern");
    EXPECT_LE(sample.target_images.abs().max().item<float>(), 1.f);
    EXPECT_LE(sample.input.images.abs().max().item<float>(), 1.f);
  }
  for (const std::array<double, 3>& mix : {std::array<double, 3>{1, 0, 0}, {0, 0, 1}}) {
    o.mask_mix = mix;
    SampleInfo info;
    const TrainingSample sample = make_scene_sample(statue, o, 5, {}, &info);
    for (int k = 1; k < 4; ++k) EXPECT_GT(sample.input.images[k][3].sum().item<float>(), 20.f);
    if (mix[2] > 0) {
      EXPECT_EQ(info.depth_source, "plane");
    }
  }
  o.mask_mix = {1, 2, 1};
  const TrainingSample mixed = make_sample({fern, statue}, o, 1, 1);
  EXPECT_EQ(mixed.input.images.size(0), 4);
}

}  // namespace
}  // namespace ii
