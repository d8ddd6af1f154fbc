#include "eval/weights.h"

#include <fstream>

#include <fmt/ranges.h>

#include "common/error.h"
#include "io/pth.h"
#include "io/safetensors.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

bool looks_like_safetensors(const fs::path& path) {
  // An 8-byte little-endian header length, then the JSON header's '{'.
  std::ifstream in(path, std::ios::binary);
  char head[9] = {};
  in.read(head, 9);
  return in.gcount() == 9 && head[8] == '{';
}

torch::Tensor float_tensor(const std::vector<float>& values, const std::vector<int64_t>& shape) {
  return torch::tensor(values, torch::kFloat32).reshape(shape);
}

}  // namespace

WeightMap read_weight_file(const fs::path& path) {
  if (!fs::is_regular_file(path)) fail_file(path, "no such weight file");
  WeightMap out;
  if (looks_like_safetensors(path)) {
    for (const auto& [name, t] : read_safetensors(path).tensors) out[name] = float_tensor(t.to_float(), t.shape);
  } else {
    for (const auto& [name, t] : read_pth_tensors(path)) out[name] = float_tensor(t.to_float(), t.shape);
  }
  if (out.empty()) fail_file(path, "holds no tensors");
  return out;
}

torch::Tensor take_weight(const WeightMap& weights, const std::string& key, const std::vector<int64_t>& shape,
                          const fs::path& file, const std::string& hint) {
  const auto it = weights.find(key);
  if (it == weights.end()) fail_file(file, "no tensor {} ({})", key, hint);
  if (it->second.sizes() != c10::IntArrayRef(shape))
    fail_file(file, "{} has shape [{}], expected [{}] ({})", key, fmt::join(it->second.sizes(), ", "),
              fmt::join(shape, ", "), hint);
  return it->second;
}

}  // namespace ii
