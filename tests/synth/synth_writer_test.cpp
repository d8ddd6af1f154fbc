// Writing synthetic scenes in the LLFF / SPIn-NeRF layout: the project's reader loads them
// with the right views, test views, masks and cameras; same seed, same bytes.
#include <gtest/gtest.h>

#include <map>

#include "data/scene.h"
#include "io/image.h"
#include "io/npy.h"
#include "synth/synth_writer.h"
#include "test_support.h"

namespace ii::synth {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace synth_writer_test {

namespace fs = std::filesystem;

SynthOptions tiny() {
  SynthOptions o;
  o.views = 6;
  o.test_views = 3;
  o.width = 48;
  o.height = 40;
  o.object = ObjectSource::procedural;
  return o;
}

std::map<std::string, std::string> folder_bytes(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) out[fs::relative(e.path(), dir).string()] = test::file_bytes(e.path());
  return out;
}

TEST(SynthWriter, ReaderLoadsViewsTestViewsMasksAndCameras) {
  const fs::path dir = test::temp_dir("synth-writer") / "scene";
  const SynthScene scene = generate_scene(tiny(), 21);
  SynthWriteOptions options;
  options.degrade = Degradation::blur;
  int last_done = 0, calls = 0;
  options.progress = [&](int done, int total) {
    EXPECT_EQ(total, 9);
    EXPECT_EQ(done, last_done + 1);
    last_done = done;
    ++calls;
  };
  const SynthWriteSummary summary = write_synth_scene(scene, dir, options);
  EXPECT_EQ(calls, 9);
  EXPECT_EQ(summary.views, 6);
  EXPECT_EQ(summary.test_views, 3);
  EXPECT_EQ(summary.degradation, "blur");
  EXPECT_GT(summary.object_fraction, 0.005);
  EXPECT_FALSE(fs::exists(dir.string() + ".partial"));

  const Scene loaded = load_scene(dir);
  EXPECT_EQ(loaded.format, "llff");
  EXPECT_TRUE(loaded.warnings.empty());
  ASSERT_EQ(loaded.views.size(), 6u);
  ASSERT_EQ(loaded.test_views.size(), 3u);
  auto check = [](const View& v, const NamedCamera& expected) {
    EXPECT_EQ(v.name, expected.name);
    ASSERT_TRUE(v.mask_path.has_value()) << v.name;
    const Intrinsics& K = v.camera.K;
    const Intrinsics& E = expected.camera.K;
    EXPECT_EQ(K.width, E.width);
    EXPECT_EQ(K.height, E.height);
    EXPECT_NEAR(K.fx, E.fx, 1e-5);
    EXPECT_NEAR(K.fy, E.fy, 1e-5);
    EXPECT_NEAR(K.cx, E.cx, 1e-5);
    EXPECT_NEAR(K.cy, E.cy, 1e-5);
    EXPECT_LT((v.camera.c2w - expected.camera.c2w).cwiseAbs().maxCoeff(), 1e-5) << v.name;
  };
  for (size_t i = 0; i < 6; ++i) check(loaded.views[i], scene.views[i]);
  for (size_t i = 0; i < 3; ++i) check(loaded.test_views[i], scene.test_views[i]);
  ASSERT_TRUE(loaded.near && loaded.far);
  EXPECT_GT(*loaded.near, 0);
  EXPECT_GT(*loaded.far, *loaded.near);

  // Images: training views show the object, test views and clean/ do not; the written mask
  // is the renderer's.
  const SynthRenderer renderer(scene);
  const SynthViewImages r = renderer.render(scene.views[2].camera);
  const Image written = load_view_image(loaded.views[2]);
  const Image clean = read_image_rgb(dir / "clean" / "view_002.png");
  const Image mask = *load_view_mask(loaded.views[2]);
  ASSERT_EQ(written.width, 48);
  for (size_t i = 0; i < written.pixels.size(); ++i) {
    EXPECT_NEAR(written.pixels[i], r.with_object.pixels[i], 0.5f / 255 + 1e-6f);
    EXPECT_NEAR(clean.pixels[i], r.clean.pixels[i], 0.5f / 255 + 1e-6f);
  }
  EXPECT_EQ(mask.pixels, r.mask.pixels);
  const Image test_image = load_view_image(loaded.test_views[1]);
  EXPECT_EQ(test_image.pixels, read_image_rgb(dir / "clean" / "test_001.png").pixels);
  EXPECT_TRUE(fs::exists(dir / "images_4" / "test_label" / "test_001.png"));

  // Depth: float32 (H, W) z-depth, as the training sampler reads it.
  const NpyArray depth = read_npy(dir / "depth" / "view_002.npy");
  EXPECT_EQ(depth.dtype, "f4");
  EXPECT_EQ(depth.shape, (std::vector<int64_t>{40, 48}));
  EXPECT_EQ(depth.as_float(), r.depth.pixels);
  EXPECT_EQ(read_npy(dir / "depth" / "test_001.npy").as_float(),
            renderer.render(scene.test_views[1].camera, false).clean_depth.pixels);
  // depth_clean/: the depth of clean/, which differs from depth/ where the object stands.
  const std::vector<float> clean_depth = read_npy(dir / "depth_clean" / "view_002.npy").as_float();
  EXPECT_EQ(clean_depth, r.clean_depth.pixels);
  EXPECT_NE(clean_depth, r.depth.pixels);

  // synth.json names the reference and context views; reference.png exists.
  const nlohmann::json j = read_synth_json(dir);
  EXPECT_EQ(j["seed"].get<uint64_t>(), 21u);
  EXPECT_EQ(j["reference"], scene.views[scene.reference].name);
  ASSERT_EQ(j["context"].size(), 4u);
  EXPECT_EQ(j["context"][0], j["reference"]);
  EXPECT_EQ(j["views"].size(), 6u);
  EXPECT_EQ(j["test_views"].size(), 3u);
  EXPECT_EQ(j["image_folder"], "images_4");
  EXPECT_EQ(probe_image(dir / "reference.png").width, 48);
  for (const auto& name : j["views"]) EXPECT_TRUE(fs::exists(dir / "clean" / (name.get<std::string>() + ".png")));
}

TEST(SynthWriter, PoseRowsInvertTheReadersConversion) {
  const SynthScene scene = generate_scene(tiny(), 5);
  const Camera& c = scene.views[1].camera;
  const auto row = llff_pose_row(c, 4, 0.5, 9.0);
  EXPECT_DOUBLE_EQ(row[4], 40 * 4);       // H
  EXPECT_DOUBLE_EQ(row[9], 48 * 4);       // W
  EXPECT_DOUBLE_EQ(row[14], c.K.fx * 4);  // f
  EXPECT_DOUBLE_EQ(row[15], 0.5);
  EXPECT_DOUBLE_EQ(row[16], 9.0);
  for (int r = 0; r < 3; ++r) {
    EXPECT_DOUBLE_EQ(row[r * 5 + 1], c.c2w(r, 0));   // right
    EXPECT_DOUBLE_EQ(row[r * 5 + 0], -c.c2w(r, 1));  // down = -up
    EXPECT_DOUBLE_EQ(row[r * 5 + 2], c.c2w(r, 2));   // back
    EXPECT_DOUBLE_EQ(row[r * 5 + 3], c.c2w(r, 3));
  }
}

TEST(SynthWriter, SameSeedSameBytesOtherSeedOtherBytes) {
  const fs::path root = test::temp_dir("synth-bytes");
  SynthWriteOptions options;
  options.degrade = Degradation::mixed;
  write_synth_scene(generate_scene(tiny(), 8), root / "a", options);
  write_synth_scene(generate_scene(tiny(), 8), root / "b", options);
  write_synth_scene(generate_scene(tiny(), 9), root / "c", options);
  const auto a = folder_bytes(root / "a"), b = folder_bytes(root / "b"), c = folder_bytes(root / "c");
  EXPECT_GT(a.size(), 30u);
  EXPECT_EQ(a, b);
  EXPECT_NE(a.at("images_4/view_000.png"), c.at("images_4/view_000.png"));
  EXPECT_NE(a.at("poses_bounds.npy"), c.at("poses_bounds.npy"));
}

TEST(SynthWriter, DepthIsOptional) {
  const fs::path dir = test::temp_dir("synth-no-depth") / "scene";
  SynthWriteOptions options;
  options.write_depth = false;
  write_synth_scene(generate_scene(tiny(), 4), dir, options);
  EXPECT_FALSE(fs::exists(dir / "depth"));
  EXPECT_FALSE(fs::exists(dir / "depth_clean"));
  EXPECT_TRUE(read_synth_json(dir)["depth"].is_null());
  EXPECT_EQ(load_scene(dir).views.size(), 6u);
}

TEST(SynthWriter, ReplacesAnEarlierSceneButNotOtherFolders) {
  const fs::path root = test::temp_dir("synth-replace");
  const SynthScene scene = generate_scene(tiny(), 2);
  write_synth_scene(scene, root / "scene", {});
  test::write_bytes(root / "scene" / "stale.txt", "x");
  write_synth_scene(scene, root / "scene", {});
  EXPECT_FALSE(fs::exists(root / "scene" / "stale.txt"));
  fs::create_directories(root / "mine");
  test::write_bytes(root / "mine" / "notes.txt", "keep");
  EXPECT_EQ(test::error_message([&] { write_synth_scene(scene, root / "mine", {}); }),
            (root / "mine").string() + ": exists and is not a synthetic scene (no synth.json): not overwriting it");
  EXPECT_EQ(test::file_bytes(root / "mine" / "notes.txt"), "keep");
  EXPECT_FALSE(fs::exists(root / "mine.partial"));
}


TEST(SynthWriter, InsertionSwapsWhatTheInputsAndTheTruthShow) {
  const fs::path root = test::temp_dir("synth-insert");
  const SynthScene scene = generate_scene(tiny(), 31);
  SynthWriteOptions options;
  write_synth_scene(scene, root / "remove", options);
  options.task = SynthTask::insert;
  write_synth_scene(scene, root / "insert", options);
  const auto removal = folder_bytes(root / "remove"), insertion = folder_bytes(root / "insert");
  // Inputs without the object, the edit's truth with it; masks and cameras as for removal.
  EXPECT_EQ(insertion.at("images_4/view_002.png"), removal.at("clean/view_002.png"));
  EXPECT_EQ(insertion.at("clean/view_002.png"), removal.at("images_4/view_002.png"));
  EXPECT_EQ(insertion.at("images_4/label/view_002.png"), removal.at("images_4/label/view_002.png"));
  EXPECT_EQ(insertion.at("depth/view_002.npy"), removal.at("depth_clean/view_002.npy"));
  EXPECT_EQ(insertion.at("original/test_001.png"), removal.at("images_4/test_001.png"));
  EXPECT_EQ(insertion.at("images_4/test_label/test_001.png"), removal.at("images_4/test_label/test_001.png"));
  EXPECT_NE(insertion.at("images_4/test_001.png"), removal.at("images_4/test_001.png"));
  const std::string reference = read_synth_json(root / "insert")["reference"];
  EXPECT_EQ(insertion.at("reference.png"), removal.at("images_4/" + reference + ".png"));
  EXPECT_EQ(read_synth_json(root / "insert")["task"], "insert");
  EXPECT_EQ(read_synth_json(root / "remove")["task"], "remove");
  EXPECT_EQ(removal.count("original/test_001.png"), 0u);
  EXPECT_EQ(test::error_message([] { parse_synth_task("erase"); }),
            "--task: unknown task 'erase' (expected remove or insert)");
}

TEST(SynthScene, SeveralObjectsStandApart) {
  SynthOptions o = tiny();
  o.objects = 3;
  const SynthScene scene = generate_scene(o, 5);
  EXPECT_EQ(scene.description["object"]["parts"].size(), 3u);
  EXPECT_GT(scene.object_radius, generate_scene(tiny(), 5).object_radius);  // spread around the centre
  o.objects = 4;
  EXPECT_EQ(test::error_message([&] { generate_scene(o, 5); }), "synth: 1 to 3 objects (got 4)");
  o.objects = 2;
  o.object = ObjectSource::splat;
  EXPECT_EQ(test::error_message([&] { generate_scene(o, 5); }),
            "synth: several objects are procedural: use --object procedural or mixed");
}

}  // namespace synth_writer_test
}  // namespace
}  // namespace ii::synth
