#pragma once
// Tensor files as LibTorch tensors: the one layer that tells safetensors from .pth, converts
// their tensors (io/safetensors.h, io/pth.h: plain bytes) to torch::Tensor and back, and
// writes safetensors. Checkpoints, metric weights and training states all go through it.
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "common/torch.h"

#include "io/pickle.h"
#include "io/safetensors.h"

namespace ii {

using TensorMap = std::map<std::string, torch::Tensor>;

// Whether `path` is a safetensors file (an 8-byte header length, then the header's '{');
// anything else is read as a PyTorch .pth.
bool is_safetensors_file(const std::filesystem::path& path);

// A stored tensor as a CPU tensor of its own dtype (F64 F32 F16 BF16 I64 I32 I16 I8 U8 BOOL);
// another dtype is an error naming `file`.
torch::Tensor tensor_from_data(const TensorData& data, const std::filesystem::path& file);
// The same without a copy: the tensor takes the bytes over.
torch::Tensor tensor_from_data(TensorData&& data, const std::filesystem::path& file);
torch::Tensor tensor_from_pth(const PthTensor& tensor, const std::filesystem::path& file);
// The other way: a tensor's bytes (any device; contiguous copy) under its safetensors dtype.
TensorData data_from_tensor(const torch::Tensor& tensor);

// Every tensor of a safetensors or .pth file, in its own dtype.
TensorMap read_tensor_file(const std::filesystem::path& path);
// A safetensors file's tensors over its mapped bytes, read in at once (MAP_POPULATE) and never
// copied; the mapping lives as long as any of them. For weights that are copied on at once
// (to a GPU: 1.2 GB read 3x faster than through read_tensor_file). Never write into them: the
// mapping is read-only. `metadata` (optional) gets the file's __metadata__.
TensorMap map_safetensors_tensors(const std::filesystem::path& path,
                                  std::map<std::string, std::string>* metadata = nullptr);

// Writes named tensors as safetensors, in the order given (atomic).
void write_tensor_file(const std::filesystem::path& path,
                       const std::vector<std::pair<std::string, torch::Tensor>>& tensors,
                       const std::map<std::string, std::string>& metadata = {});

}  // namespace ii
