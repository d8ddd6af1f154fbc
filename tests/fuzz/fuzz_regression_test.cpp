// Replays, in the normal suite, what the fuzz targets were given: the hand-made seeds must
// be accepted, and every input a fuzzer once failed on (tests/fuzz/regressions/<target>/,
// kept after the fix) must be refused with an ii::Error and nothing worse.
#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <sstream>

#include "fuzz_target.h"
#include "test_support.h"

namespace ii::fuzz {
namespace {

namespace fs = std::filesystem;

const fs::path kRegressions = fs::path(INSTAINPAINT_SOURCE_DIR) / "tests" / "fuzz" / "regressions";

TEST(FuzzTargets, EveryParserHasOne) {
  std::set<std::string> names;
  for (const FuzzTarget& t : targets()) names.insert(t.name);
  EXPECT_EQ(names, (std::set<std::string>{"box", "camera_json", "click", "colmap_binary", "colmap_text", "image", "llff",
                                          "mask_folder", "model_catalogue", "nerfstudio", "npy", "pickle", "ply", "pth",
                                          "reconstruct_checkpoint", "safetensors", "sog", "spz", "view_box"}));
}

TEST(FuzzTargets, HandMadeSeedsAreAccepted) {
  for (const FuzzTarget& t : targets()) {
    const std::vector<std::string> seeds = t.seeds();
    EXPECT_FALSE(seeds.empty()) << t.name;
    for (size_t k = 0; k < seeds.size(); ++k) {
      const auto* data = reinterpret_cast<const uint8_t*>(seeds[k].data());
      try {
        t.run(data, seeds[k].size());
      } catch (const Error& e) {
        ADD_FAILURE() << t.name << " seed " << k << ": " << e.what();
      }
    }
  }
}

TEST(FuzzTargets, PastFindingsAreRefusedCleanly) {
  if (!fs::exists(kRegressions)) GTEST_SKIP() << "no regression inputs";
  int replayed = 0;
  for (const auto& folder : fs::directory_iterator(kRegressions)) {
    const FuzzTarget* t = find_target(folder.path().filename().string());
    ASSERT_TRUE(t) << "regression folder without a target: " << folder.path();
    for (const auto& file : fs::directory_iterator(folder.path())) {
      const std::string bytes = test::file_bytes(file.path());
      const auto* data = reinterpret_cast<const uint8_t*>(bytes.data());
      SCOPED_TRACE(file.path().string());
      test::error_message([&] { t->run(data, bytes.size()); });
      ++replayed;
    }
  }
  EXPECT_GT(replayed, 0);
}

}  // namespace
}  // namespace ii::fuzz
