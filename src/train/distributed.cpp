#include "train/distributed.h"

#include <spdlog/spdlog.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>

#include "common/error.h"
#include "common/torch_compat.h"
#include "model/device.h"

// LibTorch compiles these headers only when the consumer defines the backend macros.
#if II_HAS_C10D_GLOO
#ifndef USE_C10D_GLOO
#define USE_C10D_GLOO 1
#endif
#include <torch/csrc/distributed/c10d/ProcessGroupGloo.hpp>
#endif
#if II_HAS_C10D_NCCL
#ifndef USE_C10D_NCCL
#define USE_C10D_NCCL 1
#endif
#include <torch/csrc/distributed/c10d/ProcessGroupNCCL.hpp>
#endif
#include <torch/csrc/distributed/c10d/TCPStore.hpp>

namespace ii {

namespace {

// The rendezvous store: libuv's server where LibTorch asks for it (2.4+ by default), the
// classic one where this LibTorch was built without libuv and refuses the request.
c10::intrusive_ptr<c10d::TCPStore> make_store(const std::string& host, c10d::TCPStoreOptions options) {
#if II_TCPSTORE_HAS_LIBUV_OPTION
  if (options.useLibUV) {
    try {
      return c10::make_intrusive<c10d::TCPStore>(host, options);
    } catch (const std::exception& e) {
      if (std::string(e.what()).find("without libuv") == std::string::npos) throw;
      options.useLibUV = false;
    }
  }
#endif
  return c10::make_intrusive<c10d::TCPStore>(host, options);
}

// An integer environment variable in [lo, hi]; `fallback` when unset or empty.
int env_int(const char* name, int fallback, int lo, int hi) {
  const char* value = std::getenv(name);
  if (!value || !*value) return fallback;
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(value, &end, 10);
  if (errno != 0 || *end != '\0' || v < lo || v > hi)
    fail("environment variable {}='{}' is not an integer in [{}, {}]", name, value, lo, hi);
  return static_cast<int>(v);
}

}  // namespace

DistributedConfig DistributedConfig::from_environment() {
  DistributedConfig c;
  c.world_size = env_int("WORLD_SIZE", 1, 1, 1 << 20);
  c.rank = env_int("RANK", 0, 0, c.world_size - 1);
  c.local_rank = env_int("LOCAL_RANK", c.rank, 0, 1 << 20);
  c.master_port = env_int("MASTER_PORT", c.master_port, 1, 65535);
  if (const char* addr = std::getenv("MASTER_ADDR"); addr && *addr) c.master_addr = addr;
  if (c.world_size > 1 && !std::getenv("MASTER_ADDR"))
    spdlog::warn("WORLD_SIZE={} without MASTER_ADDR: using {}", c.world_size, c.master_addr);
  return c;
}

torch::Device rank_device(const std::string& device, const DistributedConfig& config) {
  if (device != "cuda") return torch::kCPU;
  resolve_device(device);  // refuses, with the reason, when LibTorch sees no GPU
  return torch::Device(torch::kCUDA, config.local_rank % std::max<int64_t>(1, torch::cuda::device_count()));
}

std::vector<std::string> available_distributed_backends() {
  std::vector<std::string> out;
  if (II_HAS_C10D_GLOO) out.push_back("gloo");
  if (II_HAS_C10D_NCCL) out.push_back("nccl");
  return out;
}

struct ProcessGroup::Impl {
  c10::intrusive_ptr<c10d::Store> store;
  c10::intrusive_ptr<compat::CollectiveGroup> group;
};

void ProcessGroup::lost_contact(const std::string& what, const std::exception& e) const {
  fail("distributed training: rank {} of {} lost contact with the other processes during {} (a process "
       "exited or did not answer within {} s): {}",
       config_.rank, config_.world_size, what, config_.timeout.count(), e.what());
}

ProcessGroup::ProcessGroup(const DistributedConfig& config, const torch::Device& device)
    : config_(config), impl_(std::make_unique<Impl>()) {
  // Gloo writes to its peers with writev, which raises SIGPIPE when a peer has gone: without this
  // the survivor died of the signal (1 run in 10) instead of failing with the message below.
  std::signal(SIGPIPE, SIG_IGN);
  backend_ = config.backend;
  if (backend_ == "auto") backend_ = device.is_cuda() ? "nccl" : "gloo";
  if (backend_ != "gloo" && backend_ != "nccl") fail("unknown distributed backend '{}' (gloo, nccl)", backend_);
  if ((backend_ == "gloo" && !II_HAS_C10D_GLOO) || (backend_ == "nccl" && !II_HAS_C10D_NCCL))
    fail("distributed backend {} is not built in (this build has: {})", backend_,
         available_distributed_backends().empty() ? std::string("none")
                                                  : fmt::format("{}", fmt::join(available_distributed_backends(), ", ")));
  const auto timeout = std::chrono::duration_cast<std::chrono::milliseconds>(config.timeout);
  try {
    c10d::TCPStoreOptions options;
    options.port = static_cast<uint16_t>(config.master_port);
    options.isServer = config.rank == 0;
    options.numWorkers = static_cast<size_t>(config.world_size);
    options.waitWorkers = true;
    options.timeout = timeout;
    impl_->store = make_store(config.master_addr, options);
  } catch (const std::exception& e) {
    fail("distributed training: rank {} of {} could not meet the others at {}:{} within {} s: {}", config.rank,
         config.world_size, config.master_addr, config.master_port, config.timeout.count(), e.what());
  }
  try {
#if II_HAS_C10D_GLOO
    if (backend_ == "gloo") {
      auto options = c10d::ProcessGroupGloo::Options::create(timeout);
      // Loopback when every process is on this machine, else the interface that reaches
      // the master (Gloo resolves this machine's host name).
      const bool local = config.master_addr == "127.0.0.1" || config.master_addr == "localhost";
      options->devices.push_back(local ? c10d::ProcessGroupGloo::createDeviceForHostname("127.0.0.1")
                                       : c10d::ProcessGroupGloo::createDefaultDevice());
      impl_->group = c10::make_intrusive<c10d::ProcessGroupGloo>(impl_->store, config.rank, config.world_size, options);
    }
#endif
#if II_HAS_C10D_NCCL
    if (backend_ == "nccl") {
      auto options = c10d::ProcessGroupNCCL::Options::create();
      options->timeout = timeout;
      impl_->group = c10::make_intrusive<c10d::ProcessGroupNCCL>(impl_->store, config.rank, config.world_size, options);
    }
#endif
  } catch (const std::exception& e) {
    fail("distributed training: rank {} of {} could not connect the {} process group: {}", config.rank,
         config.world_size, backend_, e.what());
  }
  spdlog::debug("rank {} of {}: {} process group via {}:{}", config.rank, config.world_size, backend_,
                config.master_addr, config.master_port);
}

ProcessGroup::~ProcessGroup() = default;

void ProcessGroup::allreduce_mean(const std::vector<torch::Tensor>& tensors, const std::string& what) {
  if (tensors.empty()) return;
  torch::NoGradGuard no_grad;
  std::vector<torch::Tensor> flat;
  for (const torch::Tensor& t : tensors) flat.push_back(t.reshape({-1}));
  std::vector<torch::Tensor> buffer{torch::cat(flat)};
  try {
    impl_->group->allreduce(buffer)->wait();
  } catch (const std::exception& e) {
    lost_contact(what, e);
  }
  buffer[0].div_(config_.world_size);
  int64_t offset = 0;
  for (const torch::Tensor& t : tensors) {
    t.copy_(buffer[0].narrow(0, offset, t.numel()).view_as(t));
    offset += t.numel();
  }
}

void ProcessGroup::broadcast(const std::vector<torch::Tensor>& tensors, int root, const std::string& what) {
  torch::NoGradGuard no_grad;
  for (const torch::Tensor& t : tensors) {
    std::vector<torch::Tensor> one{t.contiguous()};
    c10d::BroadcastOptions options;
    options.rootRank = root;
    try {
      impl_->group->broadcast(one, options)->wait();
    } catch (const std::exception& e) {
      lost_contact(what, e);
    }
    if (!one[0].is_same(t)) t.copy_(one[0]);
  }
}

void ProcessGroup::barrier(const std::string& what) {
  try {
    impl_->group->barrier()->wait();
  } catch (const std::exception& e) {
    lost_contact(what, e);
  }
}

}  // namespace ii
