#pragma once
// Where the network and the renderer run, and moving data there. Everything here also works
// in a CPU-only LibTorch: "auto" then means the CPU and "cuda" is refused with the reason.
#include <future>
#include <string>

#include "common/torch.h"

#include "model/network.h"

namespace ii {

// "auto" (CUDA when LibTorch sees a GPU, else the CPU), "cpu", "cuda" or "cuda:N".
torch::Device resolve_device(const std::string& name);

// bf16 on a GPU (tensor cores) and on CPUs with native bf16 dot products, else float32.
Precision default_precision(const torch::Device& device);

// The process's thread plan (common/parallel.h: plan_threads) for `threads` (0 or less:
// $OMP_NUM_THREADS when set, else every core), and LibTorch's CPU threads as it says.
void set_cpu_threads(int threads, bool work_on_gpu = false);

// Where and how the network runs, set up once by every command that runs it: the device by
// name (resolve_device), the CPU threads for work there (set_cpu_threads) and the precision by name ("fp32",
// "bf16", or "auto" = default_precision of the device).
struct Runtime {
  torch::Device device = torch::kCPU;
  Precision precision = Precision::Float32;
};
Runtime set_up_runtime(const std::string& device, int threads, const std::string& precision);

// Copies a CPU tensor to `device`. To a GPU it goes through page-locked (pinned) memory so
// that the copy is one DMA transfer issued without waiting (the caller's next kernels on
// the same stream are ordered after it). On the CPU the tensor is returned as is.
torch::Tensor to_device(const torch::Tensor& t, const torch::Device& device);

// Creates the device's context on another thread (a GPU's takes a few hundred ms at its first
// allocation), so that a caller overlaps it with reading files; wait for the future before
// relying on it. For the CPU nothing to do: an empty future.
std::future<void> start_device(const torch::Device& device);

// Waits for the device's queued work (a no-op on the CPU): timings must end with it.
void synchronize(const torch::Device& device);

// Peak memory since the last reset, in GiB: on a GPU what LibTorch's allocator handed out,
// on the CPU the process's peak resident memory (Linux VmHWM).
void reset_peak_memory(const torch::Device& device);
double peak_memory_gb(const torch::Device& device);

}  // namespace ii
