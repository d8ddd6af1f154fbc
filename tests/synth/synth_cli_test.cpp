// `instainpaint synth` end to end: runs the built executable (beside the tests' folder);
// skipped when it has not been built.
#include <gtest/gtest.h>

#include "data/scene.h"
#include "synth/synth_writer.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

TEST(SynthCli, WritesScenesTheReaderLoads) {
  II_REQUIRE_CLI(exe);
  const fs::path dir = test::temp_dir("synth-cli");
  const fs::path log = dir / "log.txt";
  ASSERT_EQ(
      test::run_command(exe.string() + " synth --out '" + (dir / "out").string() +
                            "' --scenes 2 --seed 3 --views 4 --test-views 2 --width 32 --height 24 --object procedural "
                            "--degrade telea --threads 1",
                        log),
      0)
      << test::file_bytes(log);
  const std::string output = test::file_bytes(log);
  EXPECT_NE(output.find("scene 2/2"), std::string::npos) << output;
  EXPECT_NE(output.find("wrote 2 scene(s)"), std::string::npos) << output;
  for (const char* name : {"scene_000", "scene_001"}) {
    const Scene s = load_scene(dir / "out" / name);
    EXPECT_EQ(s.views.size(), 4u);
    EXPECT_EQ(s.test_views.size(), 2u);
    EXPECT_TRUE(s.has_masks());
    const nlohmann::json j = synth::read_synth_json(dir / "out" / name);
    EXPECT_EQ(j["reference_degradation"], "telea");
    EXPECT_EQ(j["generator"]["run_seed"], 3);
  }
  EXPECT_NE(test::file_bytes(dir / "out" / "scene_000" / "poses_bounds.npy"),
            test::file_bytes(dir / "out" / "scene_001" / "poses_bounds.npy"));
  // scene-info reads what synth wrote.
  ASSERT_EQ(test::run_command(exe.string() + " scene-info --scene '" + (dir / "out" / "scene_001").string() + "'", log),
            0)
      << test::file_bytes(log);
  EXPECT_NE(test::file_bytes(log).find("views   4 (4 with object masks), test views 2"), std::string::npos)
      << test::file_bytes(log);
}

TEST(SynthCli, BadArgumentsAreClearErrors) {
  II_REQUIRE_CLI(exe);
  const fs::path dir = test::temp_dir("synth-cli-bad");
  const fs::path log = dir / "log.txt";
  EXPECT_EQ(test::run_command(exe.string() + " synth --out '" + (dir / "o").string() + "' --views 2", log), 1);
  EXPECT_NE(test::file_bytes(log).find("error: synth: need at least 4 views (got 2)"), std::string::npos)
      << test::file_bytes(log);
  EXPECT_NE(test::run_command(exe.string() + " synth --out '" + (dir / "o").string() + "' --object cube", log), 0);
  EXPECT_NE(test::file_bytes(log).find("--object"), std::string::npos) << test::file_bytes(log);
  EXPECT_EQ(test::run_command(
                exe.string() + " synth --out '" + (dir / "o").string() + "' --object splat --splats /nonexistent", log),
            1);
  EXPECT_NE(test::file_bytes(log).find("needs captured splats"), std::string::npos) << test::file_bytes(log);
}

}  // namespace
}  // namespace ii
