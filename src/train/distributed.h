#pragma once
// Data-parallel training over PyTorch's c10d process groups (Gloo on the CPU, NCCL on CUDA
// when LibTorch is a CUDA build), configured like torchrun: MASTER_ADDR, MASTER_PORT, RANK,
// WORLD_SIZE, LOCAL_RANK. Rank 0 hosts the rendezvous store. Every collective has a
// timeout, and a process that dies closes its connections, so the others fail with an Error
// that says so instead of waiting forever.
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "common/torch.h"

namespace ii {

struct DistributedConfig {
  int rank = 0;
  int world_size = 1;
  int local_rank = 0;
  std::string master_addr = "127.0.0.1";
  int master_port = 29500;
  std::chrono::seconds timeout{600};  // rendezvous and each collective
  std::string backend = "auto";       // auto (nccl for CUDA tensors, else gloo) | gloo | nccl

  bool enabled() const { return world_size > 1; }
  // Reads the torchrun variables; a world of one process when WORLD_SIZE is unset. Values
  // that are not integers or out of range are errors naming the variable.
  static DistributedConfig from_environment();
};

// The device a rank trains on: "cuda" gives each process of a machine its own GPU (local rank
// modulo the GPUs there) and is refused, with the reason, where LibTorch sees none; anything
// else is the CPU.
torch::Device rank_device(const std::string& device, const DistributedConfig& config);

// Which collective backends this build has ("gloo", "nccl"), for messages.
std::vector<std::string> available_distributed_backends();

class ProcessGroup {
 public:
  // Rendezvous with the other processes (rank 0 listens on master_addr:master_port).
  // `device` selects the backend under "auto". Throws Error when the others do not arrive
  // within the timeout or the backend is not built in.
  ProcessGroup(const DistributedConfig& config, const torch::Device& device = torch::kCPU);
  ~ProcessGroup();
  ProcessGroup(const ProcessGroup&) = delete;
  ProcessGroup& operator=(const ProcessGroup&) = delete;

  int rank() const { return config_.rank; }
  int world_size() const { return config_.world_size; }
  const std::string& backend() const { return backend_; }

  // In place: every tensor becomes the mean over processes (one coalesced allreduce; all
  // tensors of one dtype and device). `what` names the data in error messages.
  void allreduce_mean(const std::vector<torch::Tensor>& tensors, const std::string& what);
  // In place: every process gets root's values.
  void broadcast(const std::vector<torch::Tensor>& tensors, int root, const std::string& what);
  void barrier(const std::string& what);

 private:
  struct Impl;
  [[noreturn]] void lost_contact(const std::string& what, const std::exception& e) const;
  DistributedConfig config_;
  std::string backend_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ii
