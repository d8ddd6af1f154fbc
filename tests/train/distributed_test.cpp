// Data-parallel training over Gloo with real processes on loopback: two processes with one
// sample each end with the weights of one process with both samples, and a process that
// dies makes the other fail with a clear error instead of waiting.
#include <torch/serialize.h>
#include <gtest/gtest.h>

#include <fstream>

#include "common/torch_compat.h"
#include "model/checkpoint.h"
#include "test_support.h"
#include "train/distributed.h"
#include "train/launcher.h"
#include "train/trainer.h"
#include "train_test_util.h"

namespace ii {
namespace {
// A namespace of its own: the folder's test files are compiled together (CMake's unity build).
namespace distributed_test {

namespace fs = std::filesystem;

constexpr int kSteps = 3;

TrainerOptions test_options() {
  TrainerOptions o;
  o.schedule.total_steps = 10;
  o.schedule.warmup_steps = 2;
  // Adam turns gradient rounding differences at near-zero gradients into steps of up to lr,
  // so the weight comparison uses a small rate (the official 8e-5 is smaller still).
  o.schedule.peak_lr = 1e-4;
  o.loss.perceptual = "ssim";
  return o;
}

// Step k of the global run trains on samples 2k and 2k + 1; rank r of 2 takes 2k + r.
std::vector<TrainingSample> global_batch(int k) { return test::tiny_batch(21, 2 * k, 2); }

// Worker: one rank of a 2-process run ("train": kSteps steps, then the weights to
// DIR/rank<r>.safetensors; "die": rank 1 exits after the first step, rank 0 records the
// error it gets in DIR/rank0.error).
int data_parallel_worker(const std::string& spec) {
  const std::string mode = spec.substr(0, spec.find(':'));
  const fs::path dir = spec.substr(spec.find(':') + 1);
  DistributedConfig config = DistributedConfig::from_environment();
  config.timeout = std::chrono::seconds(30);
  try {
    auto group = std::make_shared<ProcessGroup>(config);
    // Different seeds per rank: the broadcast from rank 0 must make them equal.
    Trainer trainer(test::seeded_network(config.rank == 0 ? 1 : 2), test_options(), group);
    for (int k = 0; k < kSteps; ++k) {
      trainer.step({test::tiny_sample(21, 2 * k + config.rank)});
      if (mode == "die" && config.rank == 1) ::_exit(3);
    }
    trainer.export_model(dir / fmt::format("rank{}.safetensors", config.rank));
    // The averaged (and clipped) gradients of the last step.
    std::vector<torch::Tensor> grads;
    for (const torch::Tensor& p : trainer.parameters().tensors())
      grads.push_back(p.grad().defined() ? p.grad() : torch::zeros_like(p));
    torch::save(grads, (dir / fmt::format("rank{}.grads.pt", config.rank)).string());
  } catch (const Error& e) {
    std::ofstream(dir / fmt::format("rank{}.error", config.rank)) << e.what();
    return 1;
  }
  return 0;
}

const bool worker_registered = test::register_worker("II_TEST_DATA_PARALLEL", data_parallel_worker);

int launch_two(const std::string& spec) {
  ::setenv("II_TEST_DATA_PARALLEL", spec.c_str(), 1);
  LaunchOptions launch;
  launch.processes = 2;
  launch.grace = std::chrono::seconds(20);
  const int code = run_local_processes("/proc/self/exe", {}, launch);
  ::unsetenv("II_TEST_DATA_PARALLEL");
  return code;
}

// Gloo's headers come with Debian's libgloo-dev, not with every LibTorch (the GPU machines'
// PyTorch has none): without them the build has no data-parallel training on the CPU.
#define II_REQUIRE_GLOO() \
  if (!II_HAS_C10D_GLOO) GTEST_SKIP() << "built without Gloo's headers: no data-parallel training on the CPU"

TEST(DataParallel, TwoProcessesMatchOneWithTheCombinedBatch) {
  II_REQUIRE_GLOO();
  const fs::path dir = test::temp_dir("ddp");
  ASSERT_EQ(launch_two("train:" + dir.string()), 0);

  Trainer single(test::seeded_network(1), test_options());
  for (int k = 0; k < kSteps; ++k) single.step(global_batch(k));
  const auto& names = single.parameters().names();
  for (int rank = 0; rank < 2; ++rank) {
    const StateDict state = read_safetensors_tensors(dir / fmt::format("rank{}.safetensors", rank));
    double worst = 0;
    for (size_t i = 0; i < names.size(); ++i)
      worst = std::max(worst, (state.at(names[i]) - single.parameters().tensors()[i]).abs().max().item<double>());
    EXPECT_LT(worst, 1e-5) << "rank " << rank;
    // Averaged, not summed: the gradients equal the single process's.
    std::vector<torch::Tensor> grads;
    torch::load(grads, (dir / fmt::format("rank{}.grads.pt", rank)).string());
    ASSERT_EQ(grads.size(), names.size());
    for (size_t i = 0; i < names.size(); ++i) {
      const torch::Tensor& g = single.parameters().tensors()[i].grad();
      const torch::Tensor expected = g.defined() ? g : torch::zeros_like(grads[i]);
      // Relative to the tensor's norm, not element by element: a weight-norm direction's gradient
      // (weight_v) is projected off the direction, and its near-zero elements differ by the sums'
      // rounding (2.7e-4 of the norm with 2 threads a process). Summed instead of averaged: 1.0.
      const double error = (grads[i] - expected).norm().item<double>(), scale = expected.norm().item<double>();
      EXPECT_LE(error, 1e-3 * scale + 1e-7) << names[i] << ": " << error << " of " << scale;
    }
  }
}

TEST(DataParallel, DeadProcessMakesTheOtherFailClearly) {
  II_REQUIRE_GLOO();
  const fs::path dir = test::temp_dir("ddp-dead");
  EXPECT_EQ(launch_two("die:" + dir.string()), 3);  // rank 1's exit code
  std::ifstream in(dir / "rank0.error");
  const std::string message((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Which collective notices depends on timing (rank 1 may leave while rank 0 still reads the
  // last step's loss allreduce).
  EXPECT_EQ(message.rfind("distributed training: rank 0 of 2 lost contact with the other processes during the ", 0), 0u)
      << message;
  EXPECT_NE(message.find("allreduce (a process exited or did not answer within 30 s): "), std::string::npos) << message;
}

TEST(DataParallel, EnvironmentIsChecked) {
  ::setenv("WORLD_SIZE", "2", 1);
  ::setenv("RANK", "5", 1);
  EXPECT_EQ(test::error_message([] { DistributedConfig::from_environment(); }),
            "environment variable RANK='5' is not an integer in [0, 1]");
  ::setenv("RANK", "1", 1);
  ::setenv("MASTER_PORT", "http", 1);
  EXPECT_EQ(test::error_message([] { DistributedConfig::from_environment(); }),
            "environment variable MASTER_PORT='http' is not an integer in [1, 65535]");
  ::setenv("MASTER_PORT", "29555", 1);
  ::setenv("MASTER_ADDR", "10.0.0.1", 1);
  const DistributedConfig c = DistributedConfig::from_environment();
  EXPECT_EQ(c.rank, 1);
  EXPECT_EQ(c.local_rank, 1);
  EXPECT_EQ(c.world_size, 2);
  EXPECT_EQ(c.master_port, 29555);
  EXPECT_EQ(c.master_addr, "10.0.0.1");
  for (const char* v : {"WORLD_SIZE", "RANK", "MASTER_PORT", "MASTER_ADDR"}) ::unsetenv(v);
  EXPECT_FALSE(DistributedConfig::from_environment().enabled());
}

}  // namespace distributed_test
}  // namespace
}  // namespace ii
