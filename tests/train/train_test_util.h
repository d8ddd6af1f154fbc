#pragma once
// Small in-memory training samples for the optimisation tests: 4 input views and 2 targets
// of 32x32 around the origin, contents a pure function of (seed, index), so tests can build
// the same batch in several processes; and running the test executable as a worker process.
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include "common/torch.h"

#include "model/config.h"
#include "model/model_input.h"
#include "model/network.h"
#include "camera/trajectory.h"
#include "train/sample.h"

namespace ii::test {

inline ModelConfig micro_config(int image_channels = 4) {
  ModelConfig c = ModelConfig::from_preset("tiny");
  c.heads = 4;
  c.image_channels = image_channels;
  return c;
}

// A micro network with weights drawn from `seed` (torch's global generator).
inline Network seeded_network(uint64_t seed, int image_channels = 4) {
  torch::manual_seed(seed);
  return Network(micro_config(image_channels));
}

inline Camera ring_camera(double angle, int size) {
  Camera c;
  c.K = Intrinsics::from_fov(size, size, M_PI / 3, M_PI / 3);
  c.c2w = look_at(Eigen::Vector3d(2 * std::sin(angle), 0.3, 2 * std::cos(angle)), Eigen::Vector3d::Zero(),
                  Eigen::Vector3d::UnitY());
  return c;
}

// Smooth colour fields in [-1, 1]: a few low-frequency waves with random phases.
inline torch::Tensor smooth_images(int64_t n, int64_t size, torch::Generator& gen) {
  const torch::Tensor y = torch::linspace(0, 1, size).view({1, 1, size, 1});
  const torch::Tensor x = torch::linspace(0, 1, size).view({1, 1, 1, size});
  const torch::Tensor a = torch::rand({n, 3, 1, 1}, gen) * 6, b = torch::rand({n, 3, 1, 1}, gen) * 6;
  const torch::Tensor phase = torch::rand({n, 3, 1, 1}, gen) * 6.283;
  return 0.8 * torch::sin(a * x + b * y + phase);
}

inline TrainingSample tiny_sample(uint64_t seed, int64_t index, int size = 32, int targets = 2) {
  torch::Generator gen = at::detail::createCPUGenerator(seed * 1000003 + static_cast<uint64_t>(index));
  TrainingSample s;
  const double base = 0.3 * static_cast<double>(index % 5);
  for (int v = 0; v < 4; ++v) s.input.view_cameras.push_back(ring_camera(base + 0.25 * v, size));
  for (int m = 0; m < targets; ++m) s.target_cameras.push_back(ring_camera(base + 0.1 + 0.3 * m, size));
  compute_ray_tensors(s.input.view_cameras, s.input.rays_o, s.input.rays_d, s.input.rays_d_un, s.input.plucker);
  torch::Tensor mask = torch::zeros({4, 1, size, size});
  mask.slice(2, size / 4, size / 2).slice(3, size / 4, size / 2).fill_(1.0);
  mask[0].zero_();  // the reference has no mask
  const torch::Tensor rgb = smooth_images(4, size, gen) * (1 - mask);
  s.input.images = torch::cat({rgb, mask}, 1);
  s.target_images = smooth_images(targets, size, gen);
  s.scene = "tiny_" + std::to_string(index);
  return s;
}

inline std::vector<TrainingSample> tiny_batch(uint64_t seed, int64_t first, int count, int stride = 1) {
  std::vector<TrainingSample> batch;
  for (int i = 0; i < count; ++i) batch.push_back(tiny_sample(seed, first + i * stride));
  return batch;
}

// Runs this test executable again, with extra environment variables, as a worker process
// (see register_worker); returns its wait status.
inline int run_self_as_worker(const std::map<std::string, std::string>& env) {
  // Everything is built before fork: the child of a multi-threaded process only calls execve.
  std::vector<std::string> entries;
  for (char** e = environ; *e; ++e) entries.emplace_back(*e);
  for (const auto& [k, v] : env) entries.push_back(k + "=" + v);
  std::vector<char*> envp;
  for (std::string& e : entries) envp.push_back(e.data());
  envp.push_back(nullptr);
  char self[] = "/proc/self/exe";
  char* argv[] = {self, nullptr};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execve(self, argv, envp.data());
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

// Registers `work` to run instead of the tests when the environment variable `role` is set
// (a worker process started by run_self_as_worker or a launcher). It runs once main() has
// started, so every static object of the libraries is initialised; its return value is the
// exit code.
inline bool register_worker(const char* role, int (*work)(const std::string& value)) {
  struct Worker : ::testing::Environment {
    const char* role;
    int (*work)(const std::string&);
    Worker(const char* r, int (*w)(const std::string&)) : role(r), work(w) {}
    void SetUp() override {
      if (const char* value = std::getenv(role)) std::exit(work(value));
    }
  };
  ::testing::AddGlobalTestEnvironment(new Worker(role, work));
  return true;
}

}  // namespace ii::test
