#include "model/device.h"

#include <fstream>

#include "common/error.h"
#include "common/parallel.h"
#include "common/torch_compat.h"

#if II_HAS_CUDA_TORCH
#include <c10/cuda/CUDACachingAllocator.h>
#endif

namespace ii {

void set_cpu_threads(int threads, bool work_on_gpu) {
  const ThreadPlan plan = plan_threads(threads, work_on_gpu);
  set_thread_plan(plan);
  torch::set_num_threads(plan.compute);
}

Runtime set_up_runtime(const std::string& device, int threads, const std::string& precision) {
  Runtime r;
  r.device = resolve_device(device);
  set_cpu_threads(threads, r.device.is_cuda());
  if (precision == "fp32")
    r.precision = Precision::Float32;
  else if (precision == "bf16")
    r.precision = Precision::BFloat16;
  else if (precision == "auto")
    r.precision = default_precision(r.device);
  else
    fail("--precision: unknown precision '{}' (expected auto, fp32 or bf16)", precision);
  return r;
}

torch::Device resolve_device(const std::string& name) {
  if (name == "cpu") return torch::kCPU;
  const bool cuda = torch::cuda::is_available();
  if (name == "auto") return cuda ? torch::Device(torch::kCUDA, 0) : torch::Device(torch::kCPU);
  // "cuda" or "cuda:" and up to three digits.
  const std::string digits = name.rfind("cuda:", 0) == 0 ? name.substr(5) : (name == "cuda" ? "0" : "");
  if (digits.empty() || digits.size() > 3 || digits.find_first_not_of("0123456789") != std::string::npos)
    fail("--device: unknown device '{}' (expected auto, cpu, cuda or cuda:N)", name);
  if (!cuda)
    fail("--device {}: no CUDA device is available to LibTorch (a CPU-only build, or no GPU/driver visible)", name);
  const int index = std::stoi(digits);
  const int64_t count = static_cast<int64_t>(torch::cuda::device_count());
  if (index >= count) fail("--device {}: only {} CUDA device(s) visible", name, count);
  return torch::Device(torch::kCUDA, static_cast<c10::DeviceIndex>(index));
}

Precision default_precision(const torch::Device& device) {
  return device.is_cuda() ? Precision::BFloat16 : default_cpu_precision();
}

torch::Tensor to_device(const torch::Tensor& t, const torch::Device& device) {
  if (t.device() == device) return t;
  if (device.is_cuda() && t.is_cpu()) return t.contiguous().pin_memory().to(device, /*non_blocking=*/true);
  return t.to(device);
}

std::future<void> start_device(const torch::Device& device) {
  if (device.is_cpu()) return {};
  return std::async(std::launch::async,
                    [device] { static_cast<void>(torch::empty({1}, torch::TensorOptions().device(device))); });
}

void synchronize(const torch::Device& device) {
  if (device.is_cuda()) torch::cuda::synchronize(device.index());
}

void reset_peak_memory(const torch::Device& device) {
  if (device.is_cpu()) {
    std::ofstream("/proc/self/clear_refs") << "5";
    return;
  }
#if II_HAS_CUDA_TORCH
  // LibTorch 2.x's caching allocator answers "Invalid device argument" for a device it has not
  // set up yet, which its first allocation does (seen on an H100; unverified fix, 2026-11-25).
  static_cast<void>(torch::empty({1}, torch::TensorOptions().device(device)));
  c10::cuda::CUDACachingAllocator::resetPeakStats(device.index());
#endif
}

double peak_memory_gb(const torch::Device& device) {
  constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;
  if (device.is_cpu()) {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
      if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) * 1024.0 / kGiB;  // kB
    return 0;
  }
#if II_HAS_CUDA_TORCH
  const auto stats = c10::cuda::CUDACachingAllocator::getDeviceStats(device.index());
  return static_cast<double>(
             stats.allocated_bytes[static_cast<size_t>(c10::CachingAllocator::StatType::AGGREGATE)].peak) /
         kGiB;
#else
  return 0;
#endif
}

}  // namespace ii
