// The library's predict path: a model loaded once, predictions from files or from images and
// masks in memory.
#include <gtest/gtest.h>

#include "data/scene.h"
#include "model/cpu/dispatch.h"
#include "model/default_model.h"
#include "model/inference.h"
#include "predict/predictor.h"
#include "test_support.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace predictor_test {

namespace fs = std::filesystem;

#define II_REQUIRE_DEFAULT_MODEL() \
  if (!has_default_model()) GTEST_SKIP() << "this build has no default model"

SceneInputOptions two_views() {
  SceneInputOptions opts;
  opts.context = {"IMG_2720", "IMG_2707"};
  opts.preprocess.height = 64;
  opts.geometry.align_depth = DepthPoints::none;  // the network's output as it is
  opts.geometry.floaters.fade = 1;                // (its opacities too)
  return opts;
}

void expect_same_maps(const GaussianMaps& a, const GaussianMaps& b) {
  EXPECT_TRUE(torch::equal(a.xyz, b.xyz));
  EXPECT_TRUE(torch::equal(a.rgb, b.rgb));
  EXPECT_TRUE(torch::equal(a.opacity, b.opacity));
  EXPECT_TRUE(torch::equal(a.scale, b.scale));
  EXPECT_TRUE(torch::equal(a.rotation, b.rotation));
}

TEST(Predictor, GivesWhatTheStepsItReplacesGive) {
  II_REQUIRE_SHARED(dir, "data/statue");
  II_REQUIRE_DEFAULT_MODEL();
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  EXPECT_EQ(predictor.model_name(), kDefaultModelName);
  EXPECT_EQ(predictor.describe()["format"], "safetensors");
  EXPECT_EQ(predictor.describe()["config"], predictor.config().to_json());
  // The CPU's instruction sets and the network's kernels for float32 on it (run.json, metrics.json).
  const auto float_kernels = cpu_kernels::kernel_isa(torch::kFloat32);
  EXPECT_EQ(predictor.describe()["cpu"],
            (nlohmann::json{{"detected", cpu_isa_name(cpu_features().isa)},
                            {"amx_bf16", cpu_features().amx_bf16},
                            {"kernels", float_kernels ? cpu_isa_name(*float_kernels) : "none"}}));
  const Prediction p = predictor.predict(scene, two_views());
  ASSERT_EQ(p.maps().xyz.sizes(), (std::vector<int64_t>{1, 2, 3, 64, 80}));
  EXPECT_EQ(p.input.reference_source, "ns");

  const SceneInput si = prepare_scene_input(scene, two_views());
  const Network net = network_from_checkpoint(default_checkpoint(), "default");
  expect_same_maps(p.maps(), run_network(net, si.input, Precision::Float32));
  // One Gaussian a pixel, then 8 pixels (an eighth of 64 rows) past each frame's edges and out to
  // 16 one per 2 x 2 block (56 x 48 blocks less the dense band's 48 x 40) but those the other view
  // sees through, then those behind depth edges it does not see through, then one flat splat per
  // pixel of the reference's region.
  int64_t region = 0;
  for (float m : p.input.views.front().mask->pixels) region += m > 0.5f;
  EXPECT_GT(region, 0);
  const int64_t dropped = p.describe_geometry()["frame_margin"]["dropped"].get<int64_t>();
  const int64_t behind = p.describe_geometry()["behind_edges"]["gaussians"].get<int64_t>();
  EXPECT_EQ(p.gaussians().size(),
            2 * 64 * 80 + 2 * (96 * 80 - 80 * 64 + 56 * 48 - 48 * 40) - dropped + behind + region);
  // Loaded once, called again: the same answer.
  expect_same_maps(predictor.predict(scene, two_views()).maps(), p.maps());
}

// GeometryOptions::papers(): every step after the network off, the Gaussians the official code
// makes (one a pixel, nothing past the frames, no cover), and the record says so.
TEST(Predictor, PapersGeometryLeavesTheNetworksGaussiansAlone) {
  II_REQUIRE_SHARED(dir, "data/statue");
  II_REQUIRE_DEFAULT_MODEL();
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions opts = two_views();
  opts.geometry = GeometryOptions::papers();
  const Prediction p = predictor.predict(scene, opts);
  EXPECT_EQ(p.gaussians().size(), 2 * 64 * 80);
  const Network net = network_from_checkpoint(default_checkpoint(), "default");
  expect_same_maps(p.maps(), run_network(net, prepare_scene_input(scene, opts).input, Precision::Float32));
  const nlohmann::json record = p.describe_geometry();
  EXPECT_EQ(record["source"], "off");
  EXPECT_EQ(record["floaters"]["faded"], 0);
  EXPECT_EQ(record["frame_margin"]["gaussians"], 0);
  EXPECT_EQ(record["behind_edges"]["gaussians"], 0);
  EXPECT_EQ(record["region_cover"]["gaussians"], 0);
  // Every step's layer is there, empty, in Prediction::gaussians()'s order; no other name is.
  ASSERT_EQ(p.layers.size(), 3u);
  EXPECT_EQ(p.layers[0].name, "frame_margin");
  EXPECT_EQ(p.layers[1].name, "behind_edges");
  EXPECT_EQ(p.layers[2].name, "region_cover");
  EXPECT_EQ(p.layer("behind_edges").size(), 0);
  EXPECT_EQ(test::error_message([&] { p.layer("floaters"); }),
            "prediction: no layer 'floaters' (it has: frame_margin, behind_edges, region_cover)");
}

// By default a capture without depth maps or points gets its depth scaled to points
// triangulated from its photos: each view's maps are the network's times that view's factor.
TEST(Predictor, ScalesTheDepthToThePhotosPointsByDefault) {
  II_REQUIRE_SHARED(dir, "data/statue");
  II_REQUIRE_DEFAULT_MODEL();
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  const Prediction raw = predictor.predict(scene, two_views());
  EXPECT_EQ(raw.describe_geometry()["source"], "off");
  EXPECT_EQ(raw.geometry_kind, PointsSource::None);
  SceneInputOptions opts = two_views();
  opts.geometry.align_depth = SceneInputOptions().geometry.align_depth;
  ASSERT_EQ(opts.geometry.align_depth, DepthPoints::photos);
  opts.geometry.measured_surface.from_photos = false;  // the alignment alone (the photos' own depth: stereo_depth_test)
  SceneInputOptions scale_only = opts;
  scale_only.geometry.depth_detail.detail = 0;
  const Prediction aligned = predictor.predict(scene, scale_only);
  const nlohmann::json record = aligned.describe_geometry();
  const std::string source = record["source"];
  EXPECT_EQ(source.rfind("points triangulated from 2 views' photos (", 0), 0u) << source;
  EXPECT_EQ(aligned.geometry_kind, PointsSource::Photos);
  ASSERT_EQ(record["views"].size(), 2u);
  for (int64_t v = 0; v < 2; ++v) {
    const double s = record["views"][v]["scale"];
    EXPECT_GT(record["views"][v]["points"], 20);
    EXPECT_GT(s, 1.5) << "the default model sees the statue too near";
    EXPECT_TRUE(torch::allclose(aligned.maps().depth[0][v], raw.maps().depth[0][v] * s, 1e-4, 1e-5));
    EXPECT_TRUE(torch::allclose(aligned.maps().scale[0][v], raw.maps().scale[0][v] * s, 1e-4, 1e-7));
  }
  EXPECT_TRUE(torch::equal(aligned.maps().rgb, raw.maps().rgb));
  // The default goes on beyond the scales: each pixel's factor follows the points near it, and
  // the sizes follow the depth.
  const Prediction detailed = predictor.predict(scene, opts);
  const nlohmann::json detail = detailed.describe_geometry();
  EXPECT_EQ(detail["detail"], DepthDetailOptions().detail);
  for (int64_t v = 0; v < 2; ++v) {
    const double scale = detail["views"][v]["scale"];
    EXPECT_EQ(scale, record["views"][v]["scale"]);
    EXPECT_GT(detail["views"][v]["detail_mean"], 0.01);
    const torch::Tensor factor = detailed.maps().depth[0][v] / raw.maps().depth[0][v];
    EXPECT_GT((factor / scale - 1).abs().max().item<double>(), 0.05);
    EXPECT_TRUE(torch::allclose(detailed.maps().scale[0][v], raw.maps().scale[0][v] * factor, 1e-4, 1e-7));
  }
  // The network's own maps stay as the network gave them, beside the moved ones; with no step
  // that moves them, the two are one.
  expect_same_maps(detailed.network, raw.maps());
  EXPECT_TRUE(torch::equal(detailed.network.depth, raw.maps().depth));
  EXPECT_FALSE(torch::equal(detailed.maps().depth, detailed.network.depth));
  EXPECT_TRUE(raw.maps().depth.is_same(raw.network.depth));
}

// Each step that moves, replaces or fades the network's Gaussians returns the maps after it as a
// layer of its own: its input is left as it was, and the attributes it does not write are its
// input's tensors.
TEST(Predictor, EachCorrectionIsALayerThatLeavesItsInputAlone) {
  II_REQUIRE_SHARED(dir, "data/statue");
  II_REQUIRE_DEFAULT_MODEL();
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions opts = two_views();
  opts.geometry = SceneInputOptions().geometry;  // every step as a user gets it
  const Prediction p = predictor.predict(scene, opts);
  ASSERT_EQ(p.corrections.size(), 4u);
  const GaussianMaps& aligned = p.corrections[0].maps;
  const GaussianMaps& surfaced = p.corrections[1].maps;
  const GaussianMaps& region = p.corrections[2].maps;
  const GaussianMaps& faded = p.corrections[3].maps;
  EXPECT_EQ(p.corrections[0].name, "depth_alignment");
  EXPECT_EQ(p.corrections[1].name, "measured_surface");
  EXPECT_EQ(p.corrections[2].name, "region_surface");
  EXPECT_EQ(p.corrections[3].name, "floaters");
  EXPECT_TRUE(p.maps().depth.is_same(faded.depth));
  // The alignment moves depth, positions and sizes; colours, opacities and rotations are the network's.
  EXPECT_FALSE(torch::equal(aligned.depth, p.network.depth));
  EXPECT_TRUE(aligned.rgb.is_same(p.network.rgb));
  EXPECT_TRUE(aligned.opacity.is_same(p.network.opacity));
  EXPECT_TRUE(aligned.rotation.is_same(p.network.rotation));
  // The measured surface and the region surface each wrote their own copy, not the one before.
  EXPECT_GT(p.describe_geometry()["measured_surface"]["gaussians"], 0);
  EXPECT_FALSE(torch::equal(surfaced.depth, aligned.depth));
  EXPECT_GT(p.describe_geometry()["region_surface"]["gaussians"], 0);
  EXPECT_FALSE(torch::equal(region.rgb, surfaced.rgb));
  // The floaters fade opacities alone.
  EXPECT_GT(p.describe_geometry()["floaters"]["faded"], 0);
  EXPECT_FALSE(torch::equal(faded.opacity, region.opacity));
  EXPECT_TRUE(faded.depth.is_same(region.depth));
  EXPECT_TRUE(faded.rgb.is_same(region.rgb));
  // With every step off, every layer is the network's maps themselves: nothing is copied.
  const Prediction raw = predictor.predict(scene, two_views());
  ASSERT_EQ(raw.corrections.size(), 4u);
  for (const MapsLayer& l : raw.corrections) EXPECT_TRUE(l.maps.xyz.is_same(raw.network.xyz)) << l.name;
  expect_same_maps(p.network, raw.network);  // the network's own maps as it gave them
}

TEST(Predictor, ImagesAndMasksInMemoryEqualTheirFiles) {
  II_REQUIRE_SHARED(dir, "data/statue");
  II_REQUIRE_DEFAULT_MODEL();
  const Scene scene = load_scene(dir);
  const Predictor predictor("", torch::kCPU, Precision::Float32);
  SceneInputOptions from_files = two_views();
  from_files.reference = scene.find("IMG_2708")->image_path;  // any photo of the right size
  const Prediction files = predictor.predict(scene, from_files);

  // The same images, given in memory; the scene's own masks are not looked at.
  Scene bare = scene;
  for (View& v : bare.views) v.mask_path.reset();
  SceneInputOptions in_memory = two_views();
  in_memory.reference_image = read_image_rgb(*from_files.reference);
  for (const char* name : {"IMG_2720", "IMG_2707"}) in_memory.masks[name] = read_mask(*scene.find(name)->mask_path);
  const Prediction memory = predictor.predict(bare, in_memory);
  EXPECT_EQ(memory.input.reference_source, "image in memory");
  expect_same_maps(memory.maps(), files.maps());

  in_memory.masks["IMG_2707"] = Image(10, 10, 1);
  EXPECT_EQ(test::error_message([&] { predictor.predict(bare, in_memory); }),
            "mask for view IMG_2707: 10x10 with 1 channels, the view's image is 504x378 (one channel expected)");
  in_memory.masks.erase("IMG_2707");
  EXPECT_EQ(test::error_message([&] { predictor.predict(bare, in_memory); }),
            "view IMG_2707 has no object mask: give masks for every context view (--masks DIR or --alpha-masks)");
  in_memory.reference_image = Image(7, 5, 3);
  EXPECT_EQ(test::error_message([&] { predictor.predict(scene, in_memory); }),
            "reference image in memory: reference image is 7x5, but view IMG_2720 is 504x378 (working size 80x64): "
            "give the inpainted image at either size");
}

TEST(Predictor, BadCheckpointIsAClearError) {
  const fs::path bad = test::temp_dir("predictor") / "model.safetensors";
  test::write_bytes(bad, "not a model");
  EXPECT_NE(test::error_message([&] { Predictor(bad.string(), torch::kCPU, Precision::Float32); }).find(bad.string()),
            std::string::npos);
}

}  // namespace predictor_test
}  // namespace
}  // namespace ii
