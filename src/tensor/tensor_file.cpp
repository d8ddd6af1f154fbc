#include "tensor/tensor_file.h"

#include <cstring>
#include <fstream>
#include <memory>

#include "common/error.h"
#include "common/files.h"
#include "io/pth.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

const std::vector<std::pair<std::string, torch::ScalarType>>& dtypes() {
  static const std::vector<std::pair<std::string, torch::ScalarType>> all = {
      {"F32", torch::kFloat32}, {"F16", torch::kFloat16}, {"BF16", torch::kBFloat16}, {"F64", torch::kFloat64},
      {"I64", torch::kInt64},   {"I32", torch::kInt32},   {"I16", torch::kInt16},     {"I8", torch::kInt8},
      {"U8", torch::kUInt8},    {"BOOL", torch::kBool}};
  return all;
}

torch::ScalarType scalar_type(const std::string& dtype, const fs::path& file) {
  for (const auto& [name, type] : dtypes())
    if (name == dtype) return type;
  fail_file(file, "unsupported tensor dtype {}", dtype);
}

torch::Tensor from_bytes(const std::string& dtype, const std::vector<int64_t>& shape, const std::vector<uint8_t>& bytes,
                         const fs::path& file) {
  const torch::ScalarType type = scalar_type(dtype, file);
  return torch::from_blob(const_cast<uint8_t*>(bytes.data()), shape, torch::TensorOptions().dtype(type)).clone();
}

}  // namespace

bool is_safetensors_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  char head[9] = {};
  in.read(head, 9);
  return in.gcount() == 9 && head[8] == '{';
}

torch::Tensor tensor_from_data(const TensorData& data, const fs::path& file) {
  return from_bytes(data.dtype, data.shape, data.bytes, file);
}

torch::Tensor tensor_from_data(TensorData&& data, const fs::path& file) {
  const torch::TensorOptions options = torch::TensorOptions().dtype(scalar_type(data.dtype, file));
  if (data.bytes.empty()) return torch::empty(data.shape, options);
  auto* bytes = new std::vector<uint8_t>(std::move(data.bytes));
  return torch::from_blob(bytes->data(), data.shape, [bytes](void*) { delete bytes; }, options);
}

torch::Tensor tensor_from_pth(const PthTensor& tensor, const fs::path& file) {
  return from_bytes(tensor.dtype, tensor.shape, tensor.contiguous_bytes(), file);
}

TensorData data_from_tensor(const torch::Tensor& tensor) {
  const torch::Tensor c = tensor.detach().to(torch::kCPU).contiguous();
  TensorData d;
  for (const auto& [name, type] : dtypes())
    if (type == c.scalar_type()) d.dtype = name;
  if (d.dtype.empty()) fail("no safetensors dtype for a tensor of type {}", c10::toString(c.scalar_type()));
  d.shape.assign(c.sizes().begin(), c.sizes().end());
  d.bytes.resize(c.numel() * c.element_size());
  if (!d.bytes.empty()) std::memcpy(d.bytes.data(), c.data_ptr(), d.bytes.size());
  return d;
}

TensorMap read_tensor_file(const fs::path& path) {
  TensorMap out;
  if (is_safetensors_file(path)) {
    for (auto& [name, t] : read_safetensors(path).tensors) out[name] = tensor_from_data(std::move(t), path);
  } else {
    for (const auto& [name, t] : read_pth_tensors(path)) out[name] = tensor_from_pth(t, path);
  }
  return out;
}

TensorMap map_safetensors_tensors(const fs::path& path, std::map<std::string, std::string>* metadata) {
  const auto file = std::make_shared<const MappedFile>(path, /*populate=*/true);
  SafetensorsIndex index = index_safetensors(file->data(), file->size(), path);
  if (metadata) *metadata = std::move(index.metadata);
  TensorMap out;
  for (const SafetensorsIndex::Entry& e : index.tensors) {
    const torch::TensorOptions options = torch::TensorOptions().dtype(scalar_type(e.dtype, path));
    void* bytes = const_cast<uint8_t*>(file->data() + e.offset);
    out[e.name] = e.size == 0 ? torch::empty(e.shape, options)
                              : torch::from_blob(bytes, e.shape, [file](void*) {}, options);
  }
  return out;
}

void write_tensor_file(const fs::path& path, const std::vector<std::pair<std::string, torch::Tensor>>& tensors,
                       const std::map<std::string, std::string>& metadata) {
  std::vector<std::pair<std::string, TensorData>> data;
  data.reserve(tensors.size());
  for (const auto& [name, t] : tensors) data.emplace_back(name, data_from_tensor(t));
  write_safetensors(path, data, metadata);
}

}  // namespace ii
