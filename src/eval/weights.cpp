#include "eval/weights.h"

#include <cstdlib>

#include <fmt/ranges.h>

#include "common/error.h"
#include "tensor/tensor_file.h"

namespace ii {

namespace fs = std::filesystem;

std::optional<fs::path> env_path(const char* name) {
  const char* value = std::getenv(name);
  if (!value || !*value) return std::nullopt;
  return fs::path(value);
}

WeightMap read_weight_file(const fs::path& path) {
  if (!fs::is_regular_file(path)) fail_file(path, "no such weight file");
  WeightMap out;
  for (const auto& [name, t] : read_tensor_file(path)) out[name] = t.to(torch::kFloat32);
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
