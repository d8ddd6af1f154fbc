// Training checkpoints: exact resume, atomic writes under a kill, the official-key model
// export, and which files fit which model.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <csignal>

#include "io/safetensors.h"
#include "model/checkpoint.h"
#include "test_support.h"
#include "train/trainer.h"
#include "train_test_util.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace checkpoint_test {

namespace fs = std::filesystem;

TrainerOptions test_options() {
  TrainerOptions o;
  o.schedule.total_steps = 10;
  o.schedule.warmup_steps = 3;
  o.schedule.peak_lr = 1e-3;
  o.loss.perceptual = "ssim";
  return o;
}

// Steps [first, last) of a run whose step k trains on samples 2k and 2k+1.
std::vector<double> train_steps(Trainer& trainer, int first, int last) {
  std::vector<double> losses;
  for (int k = first; k < last; ++k) losses.push_back(trainer.step(test::tiny_batch(9, 2 * k, 2)).loss);
  return losses;
}

bool same_parameters(const Trainer& a, const Trainer& b) {
  for (size_t i = 0; i < a.parameters().tensors().size(); ++i)
    if (!torch::equal(a.parameters().tensors()[i], b.parameters().tensors()[i])) return false;
  return true;
}

// Worker process of InterruptedWriteKeepsPreviousCheckpoint: trains one step further than
// the checkpoint on disk, then saves with a file-size limit below the checkpoint's size, so
// the kernel kills it (SIGXFSZ) in the middle of writing the temporary file.
int die_while_saving(const std::string& file) {
  Trainer trainer(test::seeded_network(1), test_options());
  train_steps(trainer, 0, 3);
  const rlimit limit{64 * 1024, 64 * 1024};
  ::setrlimit(RLIMIT_FSIZE, &limit);
  trainer.save(file);
  return 0;  // not reached when the checkpoint is larger than the limit
}

const bool worker_registered = test::register_worker("II_TEST_DIE_WHILE_SAVING", die_while_saving);

TEST(TrainingCheckpoint, ResumeGivesIdenticalLosses) {
  const fs::path dir = test::temp_dir("resume");
  Trainer straight(test::seeded_network(1), test_options());
  const std::vector<double> all = train_steps(straight, 0, 5);

  Trainer first(test::seeded_network(1), test_options());
  const std::vector<double> head = train_steps(first, 0, 2);
  first.save(dir / "ck.safetensors", {{"sampler_next_index", 4}});
  // Another process would start from scratch: different initial weights, then load.
  Trainer resumed(test::seeded_network(77), test_options());
  const nlohmann::json state = resumed.load(dir / "ck.safetensors");
  EXPECT_EQ(state.at("sampler_next_index"), 4);
  EXPECT_EQ(resumed.steps_done(), 2);
  const std::vector<double> tail = train_steps(resumed, 2, 5);

  ASSERT_EQ(all.size(), 5u);
  EXPECT_EQ(head[0], all[0]);
  EXPECT_EQ(head[1], all[1]);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(tail[k], all[2 + k]) << "step " << 2 + k;
  EXPECT_TRUE(same_parameters(straight, resumed));
}

TEST(TrainingCheckpoint, InterruptedWriteKeepsPreviousCheckpoint) {
  const fs::path dir = test::temp_dir("interrupted");
  const fs::path file = dir / "checkpoint.safetensors";
  Trainer before(test::seeded_network(1), test_options());
  train_steps(before, 0, 2);
  before.save(file);
  ASSERT_GT(fs::file_size(file), 64u * 1024u);

  const int status = test::run_self_as_worker({{"II_TEST_DIE_WHILE_SAVING", file.string()}});
  ASSERT_TRUE(WIFSIGNALED(status)) << "the worker was not killed while writing (status " << status << ")";
  EXPECT_EQ(WTERMSIG(status), SIGXFSZ);
  int temporaries = 0;
  for (const auto& e : fs::directory_iterator(dir)) temporaries += e.path().filename().string().rfind(".checkpoint", 0) == 0;
  EXPECT_EQ(temporaries, 1);  // the cut write went to a temporary file

  Trainer after(test::seeded_network(5), test_options());
  after.load(file);
  EXPECT_EQ(after.steps_done(), 2);
  EXPECT_TRUE(same_parameters(before, after));
}

TEST(TrainingCheckpoint, ExportAndCheckpointLoadAsModels) {
  const fs::path dir = test::temp_dir("export");
  Trainer trainer(test::seeded_network(2), test_options());
  train_steps(trainer, 0, 1);
  trainer.export_model(dir / "model.safetensors", {{"step", 1}});
  trainer.save(dir / "checkpoint.safetensors");

  const SafetensorsFile file = read_safetensors(dir / "model.safetensors");
  ASSERT_TRUE(file.find("gaudecoder.blocks.0.attn.qkv.weight_g"));
  EXPECT_EQ(file.find("gaudecoder.blocks.0.attn.qkv.weight_g")->shape, (std::vector<int64_t>{384, 1}));
  ASSERT_TRUE(file.find("gauupsampler.mlp_rgb.2.weight_v"));
  ASSERT_TRUE(file.find("mvencoder.patch_embed.proj.weight"));
  EXPECT_FALSE(file.find("gaudecoder.blocks.0.attn.qkv.weight"));
  EXPECT_EQ(file.metadata.at("step"), "1");

  const Network& current = trainer.network();
  for (const char* name : {"model.safetensors", "checkpoint.safetensors"}) {
    const Checkpoint ck = read_checkpoint(dir / name);
    EXPECT_EQ(ck.config.embed_dim, 128);
    EXPECT_EQ(ck.config.heads, 4);  // from the stored configuration
    const Network loaded = network_from_checkpoint(ck, name);
    for (size_t i = 0; i < current.named_parameters().size(); ++i)
      EXPECT_TRUE(torch::allclose(loaded.named_parameters()[i].second, current.named_parameters()[i].second, 1e-5, 1e-7))
          << name << ": " << current.named_parameters()[i].first;
  }
}

TEST(TrainingCheckpoint, FineTuningKeepsTheFilesWeightNormSplit) {
  const fs::path dir = test::temp_dir("split");
  Trainer trainer(test::seeded_network(4), test_options());
  train_steps(trainer, 0, 2);  // v is no longer W after updates
  trainer.export_model(dir / "model.safetensors");
  const Checkpoint ck = read_checkpoint(dir / "model.safetensors", /*keep_weight_norm=*/true);
  Trainer tuned(network_from_checkpoint(ck, "model"), test_options());
  EXPECT_EQ(tuned.load_weight_norm(ck.weight_norm, "model"), 4 * 2 + 2 * 5);
  EXPECT_TRUE(same_parameters(trainer, tuned));
  EXPECT_TRUE(read_checkpoint(dir / "model.safetensors").weight_norm.empty());  // only on request
}

TEST(TrainingCheckpoint, RejectsAnotherModelOrAModelFile) {
  const fs::path dir = test::temp_dir("mismatch");
  Trainer trainer(test::seeded_network(3), test_options());
  trainer.save(dir / "checkpoint.safetensors");
  trainer.export_model(dir / "model.safetensors");
  ModelConfig other = test::micro_config();
  other.blocks = 1;
  Trainer smaller(Network(other), test_options());
  EXPECT_NE(test::error_message([&] { smaller.load(dir / "checkpoint.safetensors"); }).find("was written for another model"),
            std::string::npos);
  EXPECT_EQ(test::error_message([&] { smaller.load(dir / "model.safetensors"); }),
            (dir / "model.safetensors").string() +
                ": is not a training checkpoint (format 'instainpaint'); to start from a model's weights use --init");
}

}  // namespace checkpoint_test
}  // namespace
}  // namespace ii
