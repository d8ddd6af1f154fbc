#pragma once
// safetensors: an 8-byte little-endian header length, a JSON header mapping tensor names to
// dtype, shape and byte offsets (plus optional string metadata under "__metadata__"), then
// the raw little-endian, C-order data.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace ii {

struct TensorData {
  std::string dtype;  // F64 F32 F16 BF16 I64 I32 I16 I8 U64 U32 U16 U8 BOOL
  std::vector<int64_t> shape;
  std::vector<uint8_t> bytes;  // little-endian, C order

  int64_t numel() const;
  // Converts any numeric dtype (BOOL gives 0/1). Throws Error when bytes do not match the
  // shape or the dtype is unknown.
  std::vector<float> to_float() const;
};

size_t dtype_size(const std::string& dtype);  // bytes per element, 0 for unknown dtypes

struct SafetensorsFile {
  std::map<std::string, std::string> metadata;
  std::vector<std::pair<std::string, TensorData>> tensors;  // in file (offset) order

  const TensorData* find(const std::string& name) const;
  // Throws "<file>: no tensor NAME" when absent.
  const TensorData& at(const std::string& name, const std::filesystem::path& file_for_errors) const;
};

// Where each tensor's bytes lie, checked as parse_safetensors checks them (which copies them):
// for readers that map a file and use the bytes where they are.
struct SafetensorsIndex {
  struct Entry {
    std::string name, dtype;
    std::vector<int64_t> shape;
    size_t offset = 0, size = 0;  // bytes, from the start of the data given
  };
  std::map<std::string, std::string> metadata;
  std::vector<Entry> tensors;  // in file (offset) order
};
SafetensorsIndex index_safetensors(const uint8_t* data, size_t size, const std::filesystem::path& path);

SafetensorsFile read_safetensors(const std::filesystem::path& path);
// The same from bytes in memory; `path` only names them in error messages.
SafetensorsFile parse_safetensors(const uint8_t* data, size_t size, const std::filesystem::path& path);
// Tensors are stored in the order given; the JSON header is padded with spaces to a multiple
// of 8 bytes so the data section is 8-byte aligned. Atomic.
void write_safetensors(const std::filesystem::path& path,
                       const std::vector<std::pair<std::string, TensorData>>& tensors,
                       const std::map<std::string, std::string>& metadata = {});

}  // namespace ii
