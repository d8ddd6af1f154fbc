#pragma once
// Weight files of the fixed feature networks used by the metrics (LPIPS backbones, FID's
// Inception): a PyTorch state dict `.pth` (zip or legacy, read with the restricted reader of
// io/pth.h, nothing executed) or safetensors with the same keys; the format is taken from
// the content, not the extension.
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/torch.h"

namespace ii {

using WeightMap = std::map<std::string, torch::Tensor>;

// Every tensor of the file as float32 on the CPU, under its dotted key.
WeightMap read_weight_file(const std::filesystem::path& path);

// The path in environment variable `name`, when it is set and not empty (weight files' locations).
std::optional<std::filesystem::path> env_path(const char* name);

// weights[key], checked against `shape`. Errors: "<file>: no tensor KEY (HINT)" and
// "<file>: KEY has shape [..], expected [..] (HINT)".
torch::Tensor take_weight(const WeightMap& weights, const std::string& key, const std::vector<int64_t>& shape,
                          const std::filesystem::path& file, const std::string& hint);

}  // namespace ii
