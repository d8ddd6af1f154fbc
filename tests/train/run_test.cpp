// Whole training runs on synthetic scenes: exact resume through the sample stream and the
// log, stage 2 starting from a stage-1 model (3 -> 4 channels), run-folder rules.
#include <gtest/gtest.h>

#include <fstream>

#include "io/safetensors.h"
#include "synth/synth_scene.h"
#include "synth/synth_writer.h"
#include "test_support.h"
#include "train/run.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

class TrainingRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scenes_ = new fs::path(test::temp_dir("synth-scenes"));
    synth::SynthOptions o;
    o.views = 16;
    o.test_views = 2;
    o.width = o.height = 48;
    o.object = synth::ObjectSource::procedural;
    for (int i = 0; i < 2; ++i)
      synth::write_synth_scene(synth::generate_scene(o, 100 + i), *scenes_ / fmt::format("scene_{}", i), {});
  }
  static void TearDownTestSuite() { delete scenes_; }

  static TrainRunOptions options(const fs::path& out, int64_t steps) {
    TrainRunOptions o;
    o.scene_dirs = {*scenes_};
    o.out = out;
    o.preset = "tiny";
    o.steps = steps;
    o.batch = 2;
    o.sampler.width = o.sampler.height = 32;
    o.sampler.num_targets = 2;
    o.trainer.schedule.peak_lr = 1e-3;
    o.trainer.schedule.warmup_steps = 0;
    o.trainer.loss.perceptual = "ssim";
    o.workers = 1;
    o.val_every = 2;
    o.val_samples = 2;
    o.val_images = 1;
    o.save_every = 0;
    return o;
  }

  static std::vector<nlohmann::json> log_lines(const fs::path& run) {
    std::vector<nlohmann::json> out;
    std::ifstream in(run / "log.jsonl");
    for (std::string line; std::getline(in, line);) out.push_back(nlohmann::json::parse(line));
    return out;
  }

  static fs::path* scenes_;
};

fs::path* TrainingRun::scenes_ = nullptr;

TEST_F(TrainingRun, ResumedRunLogsTheSameLosses) {
  const fs::path dir = test::temp_dir("run-resume");
  run_training(options(dir / "straight", 4), {});
  TrainRunOptions first = options(dir / "split", 4);
  first.stop_after = 2;
  run_training(first, {});
  EXPECT_EQ(log_lines(dir / "split").size(), 3u);  // validation of the start, steps 1-2
  TrainRunOptions rest = options(dir / "split", 4);
  rest.resume = true;
  run_training(rest, {});

  const auto a = log_lines(dir / "straight"), b = log_lines(dir / "split");
  ASSERT_EQ(a.size(), 5u);
  ASSERT_EQ(b.size(), 5u);
  EXPECT_EQ(a[0]["step"], 0);
  EXPECT_EQ(a[0]["val_loss"].get<double>(), b[0]["val_loss"].get<double>());
  for (size_t i = 1; i < 5; ++i) {
    EXPECT_EQ(a[i]["step"], b[i]["step"]);
    for (const char* key : {"loss", "mse", "perceptual", "lr", "grad_norm"})
      EXPECT_EQ(a[i][key].get<double>(), b[i][key].get<double>()) << key << " at step " << i;
  }
  EXPECT_EQ(a[4]["val_loss"].get<double>(), b[4]["val_loss"].get<double>());
  EXPECT_LT(a[4]["val_loss"].get<double>(), a[0]["val_loss"].get<double>());  // it learns
  EXPECT_TRUE(fs::exists(dir / "split" / "model.safetensors"));
  EXPECT_TRUE(fs::exists(dir / "split" / "val" / "step_000004_0.png"));
}

TEST_F(TrainingRun, InpaintingStartsFromAReconstructionModel) {
  const fs::path dir = test::temp_dir("run-stages");
  TrainRunOptions stage1 = options(dir / "stage1", 2);
  stage1.sampler.stage = TrainStage::Reconstruct;
  stage1.val_every = 0;
  run_training(stage1, {});
  const SafetensorsFile rgb_model = read_safetensors(dir / "stage1" / "model.safetensors");
  EXPECT_EQ(rgb_model.find("mvencoder.patch_embed.proj.weight")->shape, (std::vector<int64_t>{128, 3, 8, 8}));

  TrainRunOptions stage2 = options(dir / "stage2", 1);
  stage2.init = dir / "stage1" / "model.safetensors";
  const Network start = initial_network(stage2);
  ASSERT_EQ(start.config().image_channels, 4);
  const torch::Tensor w = start.named_parameters()[0].second;  // patch_embed.proj.weight
  EXPECT_TRUE(torch::allclose(w.narrow(1, 3, 1), w.narrow(1, 0, 3).mean(1, true), 1e-6, 1e-7));
  run_training(stage2, {});
  EXPECT_EQ(read_safetensors(dir / "stage2" / "model.safetensors").find("mvencoder.patch_embed.proj.weight")->shape,
            (std::vector<int64_t>{128, 4, 8, 8}));
}

TEST_F(TrainingRun, FolderRules) {
  const fs::path dir = test::temp_dir("run-rules");
  TrainRunOptions resume = options(dir / "none", 1);
  resume.resume = true;
  EXPECT_EQ(test::error_message([&] { run_training(resume, {}); }),
            "--resume: " + (dir / "none" / "checkpoint.safetensors").string() + " does not exist (no run to continue in " +
                (dir / "none").string() + ")");
  TrainRunOptions once = options(dir / "once", 1);
  once.val_every = 0;
  run_training(once, {});
  EXPECT_EQ(test::error_message([&] { run_training(once, {}); }),
            "--out " + (dir / "once").string() +
                " already holds a training run; pass --resume to continue it or choose another folder");

  EXPECT_EQ(load_training_scenes({*scenes_}, {}).size(), 2u);
  EXPECT_EQ(load_training_scenes({*scenes_ / "scene_1"}, {}).size(), 1u);
  const fs::path empty = test::temp_dir("no-scenes");
  EXPECT_NE(test::error_message([&] { load_training_scenes({empty}, {}); })
                .find("--scenes: " + empty.string() + " is neither a scene nor a folder of scenes"),
            std::string::npos);
}

}  // namespace
}  // namespace ii
