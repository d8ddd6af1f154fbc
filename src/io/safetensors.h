#pragma once
// safetensors: an 8-byte little-endian header length, a JSON header mapping tensor names to
// dtype, shape and byte offsets (plus optional string metadata), then the raw data.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace ii {

struct TensorData {
  std::string dtype;  // F64 F32 F16 BF16 I64 I32 I16 I8 U8 BOOL
  std::vector<int64_t> shape;
  std::vector<uint8_t> bytes;  // little-endian, C order

  int64_t numel() const;
  std::vector<float> to_float() const;  // converts any numeric dtype
};

size_t dtype_size(const std::string& dtype);  // 0 for unknown dtypes

struct SafetensorsFile {
  std::map<std::string, std::string> metadata;
  std::vector<std::pair<std::string, TensorData>> tensors;  // in file (offset) order

  const TensorData* find(const std::string& name) const;
  // Throws "<file>: no tensor NAME" when absent.
  const TensorData& at(const std::string& name, const std::filesystem::path& file_for_errors) const;
};

SafetensorsFile read_safetensors(const std::filesystem::path& path);
void write_safetensors(const std::filesystem::path& path,
                       const std::vector<std::pair<std::string, TensorData>>& tensors,
                       const std::map<std::string, std::string>& metadata = {});

}  // namespace ii
