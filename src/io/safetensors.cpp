#include "io/safetensors.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>

#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/files.h"
#include "io/byte_reader.h"
#include "io/half.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

// The reference implementation refuses headers above 100 MB; so do we, before allocating.
constexpr uint64_t kMaxHeaderBytes = 100'000'000;

template <typename S>
void convert(const std::vector<uint8_t>& bytes, std::vector<float>& out) {
  for (size_t i = 0; i < out.size(); ++i) {
    S v;
    std::memcpy(&v, bytes.data() + i * sizeof(S), sizeof(S));
    out[i] = static_cast<float>(v);
  }
}

}  // namespace

size_t dtype_size(const std::string& dtype) {
  static const std::map<std::string, size_t> sizes = {
      {"F64", 8}, {"F32", 4}, {"F16", 2}, {"BF16", 2}, {"I64", 8}, {"I32", 4}, {"I16", 2},
      {"I8", 1},  {"U64", 8}, {"U32", 4}, {"U16", 2},  {"U8", 1},  {"BOOL", 1}};
  auto it = sizes.find(dtype);
  return it == sizes.end() ? 0 : it->second;
}

int64_t TensorData::numel() const {
  int64_t n = 1;
  for (int64_t s : shape) n *= s;
  return n;
}

std::vector<float> TensorData::to_float() const {
  const size_t item = dtype_size(dtype);
  if (item == 0) fail("cannot convert tensor of dtype {} to float", dtype);
  const int64_t n = numel();
  if (n < 0 || static_cast<uint64_t>(n) * item != bytes.size())
    fail("tensor of shape [{}] and dtype {} holds {} bytes", fmt::join(shape, ", "), dtype, bytes.size());
  std::vector<float> out(static_cast<size_t>(n));
  if (dtype == "F32") {
    if (n) std::memcpy(out.data(), bytes.data(), bytes.size());
  } else if (dtype == "F16") {
    for (size_t i = 0; i < out.size(); ++i) out[i] = half_to_float(static_cast<uint16_t>(bytes[2 * i] | (bytes[2 * i + 1] << 8)));
  } else if (dtype == "BF16") {
    // bfloat16 is the top half of a float32.
    for (size_t i = 0; i < out.size(); ++i) {
      const uint32_t bits = (static_cast<uint32_t>(bytes[2 * i]) << 16) | (static_cast<uint32_t>(bytes[2 * i + 1]) << 24);
      std::memcpy(&out[i], &bits, 4);
    }
  } else if (dtype == "F64") convert<double>(bytes, out);
  else if (dtype == "I64") convert<int64_t>(bytes, out);
  else if (dtype == "I32") convert<int32_t>(bytes, out);
  else if (dtype == "I16") convert<int16_t>(bytes, out);
  else if (dtype == "I8") convert<int8_t>(bytes, out);
  else if (dtype == "U64") convert<uint64_t>(bytes, out);
  else if (dtype == "U32") convert<uint32_t>(bytes, out);
  else if (dtype == "U16") convert<uint16_t>(bytes, out);
  else if (dtype == "U8") convert<uint8_t>(bytes, out);
  else  // BOOL
    for (size_t i = 0; i < out.size(); ++i) out[i] = bytes[i] ? 1.f : 0.f;
  return out;
}

const TensorData* SafetensorsFile::find(const std::string& name) const {
  for (const auto& kv : tensors)
    if (kv.first == name) return &kv.second;
  return nullptr;
}

const TensorData& SafetensorsFile::at(const std::string& name, const fs::path& file) const {
  const TensorData* t = find(name);
  if (!t) fail_file(file, "no tensor {}", name);
  return *t;
}

SafetensorsFile read_safetensors(const fs::path& path) {
  const MappedFile file(path);
  return parse_safetensors(file.data(), file.size(), path);
}

SafetensorsFile parse_safetensors(const uint8_t* data, size_t size, const fs::path& path) {
  SafetensorsIndex index = index_safetensors(data, size, path);
  SafetensorsFile file;
  file.metadata = std::move(index.metadata);
  for (SafetensorsIndex::Entry& e : index.tensors) {
    TensorData t;
    t.dtype = std::move(e.dtype);
    t.shape = std::move(e.shape);
    t.bytes.assign(data + e.offset, data + e.offset + e.size);
    file.tensors.emplace_back(std::move(e.name), std::move(t));
  }
  return file;
}

SafetensorsIndex index_safetensors(const uint8_t* data, size_t size, const fs::path& path) {
  if (size < 8) fail_file(path, "not a safetensors file: shorter than its 8-byte header length");
  ByteReader r(data, size, path);
  const uint64_t header_len = r.read<uint64_t>("header length");
  if (header_len > r.remaining())
    fail_file(path, "not a safetensors file: header length {} exceeds the file size {}", header_len, size);
  if (header_len > kMaxHeaderBytes)
    fail_file(path, "header length {} is above the 100 MB limit", header_len);
  const std::string header_text = r.read_string(header_len, "header");
  nlohmann::json header;
  try {
    header = nlohmann::json::parse(header_text);
  } catch (const nlohmann::json::exception& e) {
    fail_file(path, "header is not valid JSON ({})", e.what());
  }
  if (!header.is_object()) fail_file(path, "header is not a JSON object");
  const size_t data_start = r.position();
  const uint64_t data_size = r.remaining();

  SafetensorsIndex file;
  struct Entry {
    uint64_t begin, end;
    SafetensorsIndex::Entry tensor;
  };
  std::vector<Entry> entries;
  for (const auto& [name, entry] : header.items()) {
    if (name == "__metadata__") {
      if (!entry.is_object()) fail_file(path, "__metadata__ is not an object");
      for (const auto& [k, v] : entry.items()) {
        if (!v.is_string()) fail_file(path, "__metadata__ value of '{}' is not a string", k);
        file.metadata[k] = v.get<std::string>();
      }
      continue;
    }
    if (!entry.is_object() || !entry.contains("dtype") || !entry.contains("shape") || !entry.contains("data_offsets") ||
        !entry["dtype"].is_string() || !entry["shape"].is_array() || !entry["data_offsets"].is_array() ||
        entry["data_offsets"].size() != 2)
      fail_file(path, "tensor '{}' needs dtype, shape and data_offsets [begin, end]", name);
    SafetensorsIndex::Entry t;
    t.name = name;
    t.dtype = entry["dtype"].get<std::string>();
    const size_t item = dtype_size(t.dtype);
    if (item == 0) fail_file(path, "tensor '{}' has unknown dtype {}", name, t.dtype);
    // Element count saturates just above the data size: a lying shape cannot overflow into
    // a small product, and anything larger than the data is an error anyway.
    uint64_t numel = 1;
    for (const auto& d : entry["shape"]) {
      if (!d.is_number_unsigned()) fail_file(path, "tensor '{}' has a negative or non-integer dimension", name);
      const uint64_t dim = d.get<uint64_t>();
      if (dim > static_cast<uint64_t>(std::numeric_limits<int64_t>::max()))
        fail_file(path, "tensor '{}' has an implausible dimension {}", name, dim);
      t.shape.push_back(static_cast<int64_t>(dim));
    }
    for (int64_t dim : t.shape) {
      if (dim == 0) {
        numel = 0;
        break;
      }
      numel = (numel > (data_size + 1) / static_cast<uint64_t>(dim)) ? data_size + 1 : numel * static_cast<uint64_t>(dim);
    }
    const auto& off = entry["data_offsets"];
    if (!off[0].is_number_unsigned() || !off[1].is_number_unsigned())
      fail_file(path, "tensor '{}' has invalid data_offsets", name);
    const uint64_t begin = off[0].get<uint64_t>(), end = off[1].get<uint64_t>();
    if (begin > end || end > data_size)
      fail_file(path, "tensor '{}' data_offsets [{}, {}] lie outside the {}-byte data section", name, begin, end,
                data_size);
    if (numel > data_size || numel * item != end - begin)
      fail_file(path, "tensor '{}' of shape [{}] and dtype {} needs {} bytes, data_offsets give {}", name,
                fmt::join(t.shape, ", "), t.dtype,
                numel > data_size ? "more than " + std::to_string(data_size) : std::to_string(numel * item),
                end - begin);
    t.offset = data_start + begin;
    t.size = end - begin;
    entries.push_back({begin, end, std::move(t)});
  }
  std::stable_sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return a.begin != b.begin ? a.begin < b.begin : a.end < b.end;
  });
  for (size_t i = 1; i < entries.size(); ++i)
    if (entries[i].begin < entries[i - 1].end)
      fail_file(path, "tensors '{}' and '{}' overlap", entries[i - 1].tensor.name, entries[i].tensor.name);
  for (Entry& e : entries) file.tensors.push_back(std::move(e.tensor));
  return file;
}

void write_safetensors(const fs::path& path, const std::vector<std::pair<std::string, TensorData>>& tensors,
                       const std::map<std::string, std::string>& metadata) {
  nlohmann::ordered_json header = nlohmann::ordered_json::object();
  if (!metadata.empty()) header["__metadata__"] = metadata;
  std::set<std::string> names;
  uint64_t offset = 0;
  for (const auto& [name, t] : tensors) {
    if (name == "__metadata__") fail_file(path, "a tensor cannot be named __metadata__");
    if (!names.insert(name).second) fail_file(path, "tensor '{}' is given twice", name);
    const size_t item = dtype_size(t.dtype);
    if (item == 0) fail_file(path, "cannot write tensor '{}' of unknown dtype {}", name, t.dtype);
    for (int64_t d : t.shape)
      if (d < 0) fail_file(path, "tensor '{}' has a negative dimension in shape [{}]", name, fmt::join(t.shape, ", "));
    if (static_cast<uint64_t>(t.numel()) * item != t.bytes.size())
      fail_file(path, "tensor '{}': {} bytes do not match shape [{}] of {}", name, t.bytes.size(),
                fmt::join(t.shape, ", "), t.dtype);
    header[name] = {{"dtype", t.dtype}, {"shape", t.shape}, {"data_offsets", {offset, offset + t.bytes.size()}}};
    offset += t.bytes.size();
  }
  std::string text = header.dump();
  text.append((8 - text.size() % 8) % 8, ' ');  // keeps the data section 8-byte aligned
  const uint64_t len = text.size();
  // Streamed rather than assembled in memory: checkpoints can be large.
  write_file_atomic(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) fail_file(tmp, "cannot open for writing: {}", std::strerror(errno));
    out.write(reinterpret_cast<const char*>(&len), 8);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    for (const auto& kv : tensors)
      out.write(reinterpret_cast<const char*>(kv.second.bytes.data()), static_cast<std::streamsize>(kv.second.bytes.size()));
    out.flush();
    if (!out) fail_file(path, "write error (disk full?)");
  });
}

}  // namespace ii
