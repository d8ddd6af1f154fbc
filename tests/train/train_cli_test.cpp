// `instainpaint train --depth-weight` (and --own-view-weight, --size-cycle) end to end: runs the built executable (beside the tests'
// folder); skipped when it has not been built.
#include <gtest/gtest.h>

#include <fstream>

#include <nlohmann/json.hpp>

#include "common/files.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

TEST(TrainCli, DepthWeightReachesTheLossAndTheLogs) {
  II_REQUIRE_CLI(exe);
  const fs::path dir = test::temp_dir("train-cli");
  const fs::path log = dir / "log.txt";
  ASSERT_EQ(test::run_command(exe.string() + " synth --out '" + (dir / "rooms").string() +
                                  "' --scenes 1 --seed 5 --views 8 --test-views 1 --width 32 --height 32 --threads 1",
                              log),
            0)
      << read_file_text(log);
  const std::string common = exe.string() + " train --scenes '" + (dir / "rooms").string() +
                             "' --stage inpaint --preset tiny --width 32 --height 32 --inputs 4 --targets 2 --batch 1 "
                             "--steps 2 --val-every 2 --val-samples 1 --perceptual ssim --out '";
  ASSERT_EQ(test::run_command(common + (dir / "run").string() + "' --depth-weight 0.5", log), 0) << read_file_text(log);

  EXPECT_EQ(json::parse(read_file_text(dir / "run" / "run.json"))["loss"]["depth"], 0.5)
      << read_file_text(dir / "run" / "run.json");
  std::ifstream lines(dir / "run" / "log.jsonl");
  std::string line;
  int steps = 0, validations = 0;
  while (std::getline(lines, line)) {
    const json j = json::parse(line);
    if (j.contains("loss")) {
      ++steps;
      // The synthetic room has depth maps: the term is measured and part of the loss.
      EXPECT_GT(j["depth"].get<double>(), 0) << line;
      EXPECT_GT(j["loss"].get<double>(), 0.5 * j["depth"].get<double>()) << line;
    }
    if (j.contains("val_depth")) ++validations;
  }
  EXPECT_EQ(steps, 2);
  EXPECT_GE(validations, 1);

  // The own-view term: in run.json, in every step's line, and the own views' PSNR in the
  // validation's.
  ASSERT_EQ(test::run_command(common + (dir / "own").string() + "' --own-view-weight 0.5", log), 0) << read_file_text(log);
  EXPECT_EQ(json::parse(read_file_text(dir / "own" / "run.json"))["loss"]["own_view"], 0.5);
  std::ifstream own_lines(dir / "own" / "log.jsonl");
  int own_terms = 0, own_psnrs = 0;
  while (std::getline(own_lines, line)) {
    const json j = json::parse(line);
    if (j.contains("own_view")) own_terms += j["own_view"].get<double>() > 0;
    if (j.contains("val_own_psnr")) own_psnrs += j["val_own_psnr"].get<double>() > 5;
  }
  EXPECT_EQ(own_terms, 2);
  EXPECT_GE(own_psnrs, 1);

  // A size cycle: one size per step, in turn, logged; in run.json; a size that is none refused.
  ASSERT_EQ(test::run_command(common + (dir / "sizes").string() + "' --size-cycle 32,40x32", log), 0)
      << read_file_text(log);
  EXPECT_EQ(json::parse(read_file_text(dir / "sizes" / "run.json"))["size_cycle"].dump(), "[[32,32],[40,32]]");
  std::ifstream size_lines(dir / "sizes" / "log.jsonl");
  std::vector<std::string> sizes;
  while (std::getline(size_lines, line))
    if (json::parse(line).contains("size")) sizes.push_back(json::parse(line)["size"].dump());
  EXPECT_EQ(sizes, (std::vector<std::string>{"[32,32]", "[40,32]"}));
  EXPECT_NE(test::run_command(common + (dir / "bad-size").string() + "' --size-cycle 32,big", log), 0);
  EXPECT_NE(read_file_text(log).find("--size-cycle: 'big' is not a size (expected N for N x N, or WIDTHxHEIGHT)"),
            std::string::npos)
      << read_file_text(log);

  // A negative weight is refused before anything runs.
  EXPECT_NE(test::run_command(common + (dir / "bad").string() + "' --depth-weight -1", log), 0);
  // CLI11's wording of the range differs between its versions ("0.000000 to 100.000000" in
  // 2.3, "[0 - 100]" in 2.4).
  EXPECT_NE(read_file_text(log).find("--depth-weight: Value -1 not in range "), std::string::npos)
      << read_file_text(log);
  EXPECT_FALSE(fs::exists(dir / "bad"));
}

}  // namespace
}  // namespace ii
