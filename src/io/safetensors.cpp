#include "io/safetensors.h"

#include <algorithm>
#include <cstring>

#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/files.h"
#include "io/byte_reader.h"

namespace ii {

namespace fs = std::filesystem;

size_t dtype_size(const std::string& dtype) {
  static const std::map<std::string, size_t> sizes = {
      {"F64", 8}, {"F32", 4}, {"F16", 2}, {"BF16", 2}, {"I64", 8}, {"I32", 4},
      {"I16", 2}, {"I8", 1},  {"U8", 1},  {"BOOL", 1}, {"U16", 2}, {"U32", 4}, {"U64", 8}};
  auto it = sizes.find(dtype);
  return it == sizes.end() ? 0 : it->second;
}

int64_t TensorData::numel() const {
  int64_t n = 1;
  for (int64_t s : shape) n *= s;
  return n;
}

namespace {

float half_to_float(uint16_t h) {
  const uint32_t sign = (h & 0x8000u) << 16, exp = (h >> 10) & 0x1f, man = h & 0x3ff;
  uint32_t bits;
  if (exp == 0) {
    if (man == 0) {
      bits = sign;
    } else {  // subnormal: renormalise
      int e = -1;
      uint32_t m = man;
      do {
        ++e;
        m <<= 1;
      } while ((m & 0x400) == 0);
      bits = sign | ((127 - 15 - e) << 23) | ((m & 0x3ff) << 13);
    }
  } else if (exp == 31) {
    bits = sign | 0x7f800000u | (man << 13);
  } else {
    bits = sign | ((exp + 127 - 15) << 23) | (man << 13);
  }
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

template <typename S>
void convert(const std::vector<uint8_t>& bytes, std::vector<float>& out) {
  for (size_t i = 0; i < out.size(); ++i) {
    S v;
    std::memcpy(&v, bytes.data() + i * sizeof(S), sizeof(S));
    out[i] = static_cast<float>(v);
  }
}

}  // namespace

std::vector<float> TensorData::to_float() const {
  std::vector<float> out(static_cast<size_t>(numel()));
  if (dtype == "F32") {
    std::memcpy(out.data(), bytes.data(), out.size() * 4);
  } else if (dtype == "F16" || dtype == "BF16") {
    for (size_t i = 0; i < out.size(); ++i) {
      uint16_t h;
      std::memcpy(&h, bytes.data() + 2 * i, 2);
      if (dtype == "F16") {
        out[i] = half_to_float(h);
      } else {
        const uint32_t bits = static_cast<uint32_t>(h) << 16;
        std::memcpy(&out[i], &bits, 4);
      }
    }
  } else if (dtype == "F64") convert<double>(bytes, out);
  else if (dtype == "I64") convert<int64_t>(bytes, out);
  else if (dtype == "I32") convert<int32_t>(bytes, out);
  else if (dtype == "I16") convert<int16_t>(bytes, out);
  else if (dtype == "I8") convert<int8_t>(bytes, out);
  else if (dtype == "U8" || dtype == "BOOL") convert<uint8_t>(bytes, out);
  else if (dtype == "U16") convert<uint16_t>(bytes, out);
  else if (dtype == "U32") convert<uint32_t>(bytes, out);
  else if (dtype == "U64") convert<uint64_t>(bytes, out);
  else fail("cannot convert dtype {} to float", dtype);
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
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  ByteReader r(bytes.data(), bytes.size(), path);
  if (bytes.size() < 8) fail_file(path, "not a safetensors file: shorter than its 8-byte header length");
  const uint64_t header_len = r.read<uint64_t>("header length");
  if (header_len > r.remaining())
    fail_file(path, "not a safetensors file: header length {} exceeds the file size {}", header_len, bytes.size());
  const std::string header_text = r.read_string(header_len, "header");
  nlohmann::json header;
  try {
    header = nlohmann::json::parse(header_text);
  } catch (const nlohmann::json::exception& e) {
    fail_file(path, "header is not valid JSON ({})", e.what());
  }
  if (!header.is_object()) fail_file(path, "header is not a JSON object");
  const size_t data_start = r.position(), data_size = r.remaining();

  SafetensorsFile file;
  struct Entry {
    uint64_t begin, end;
    std::string name;
    TensorData tensor;
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
    TensorData t;
    t.dtype = entry["dtype"].get<std::string>();
    const size_t item = dtype_size(t.dtype);
    if (item == 0) fail_file(path, "tensor '{}' has unknown dtype {}", name, t.dtype);
    uint64_t numel = 1;
    for (const auto& d : entry["shape"]) {
      if (!d.is_number_unsigned()) fail_file(path, "tensor '{}' has a negative or non-integer dimension", name);
      const uint64_t dim = d.get<uint64_t>();
      if (dim != 0 && numel > data_size / dim) numel = data_size + 1;  // overflow guard: too big anyway
      else numel *= dim;
      t.shape.push_back(static_cast<int64_t>(dim));
    }
    const auto& off = entry["data_offsets"];
    if (!off[0].is_number_unsigned() || !off[1].is_number_unsigned())
      fail_file(path, "tensor '{}' has invalid data_offsets", name);
    const uint64_t begin = off[0].get<uint64_t>(), end = off[1].get<uint64_t>();
    if (begin > end || end > data_size)
      fail_file(path, "tensor '{}' data_offsets [{}, {}] lie outside the {}-byte data section", name, begin, end, data_size);
    if (numel > data_size || numel * item != end - begin)
      fail_file(path, "tensor '{}' of shape [{}] and dtype {} needs {} bytes, data_offsets give {}", name,
                fmt::join(t.shape, ", "), t.dtype, numel * item, end - begin);
    t.bytes.assign(bytes.begin() + data_start + begin, bytes.begin() + data_start + end);
    entries.push_back({begin, end, name, std::move(t)});
  }
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) { return a.begin < b.begin; });
  for (size_t i = 1; i < entries.size(); ++i)
    if (entries[i].begin < entries[i - 1].end)
      fail_file(path, "tensors '{}' and '{}' overlap", entries[i - 1].name, entries[i].name);
  for (Entry& e : entries) file.tensors.emplace_back(std::move(e.name), std::move(e.tensor));
  return file;
}

void write_safetensors(const fs::path& path, const std::vector<std::pair<std::string, TensorData>>& tensors,
                       const std::map<std::string, std::string>& metadata) {
  nlohmann::ordered_json header;
  if (!metadata.empty()) header["__metadata__"] = metadata;
  uint64_t offset = 0;
  for (const auto& [name, t] : tensors) {
    const size_t item = dtype_size(t.dtype);
    if (item == 0) fail_file(path, "cannot write tensor '{}' of unknown dtype {}", name, t.dtype);
    if (static_cast<uint64_t>(t.numel()) * item != t.bytes.size())
      fail_file(path, "tensor '{}': {} bytes do not match shape [{}] of {}", name, t.bytes.size(), fmt::join(t.shape, ", "), t.dtype);
    header[name] = {{"dtype", t.dtype}, {"shape", t.shape}, {"data_offsets", {offset, offset + t.bytes.size()}}};
    offset += t.bytes.size();
  }
  std::string text = header.dump();
  text.append((8 - text.size() % 8) % 8, ' ');  // data section 8-byte aligned
  std::string out;
  out.reserve(8 + text.size() + offset);
  const uint64_t len = text.size();
  out.append(reinterpret_cast<const char*>(&len), 8);
  out += text;
  for (const auto& kv : tensors) out.append(reinterpret_cast<const char*>(kv.second.bytes.data()), kv.second.bytes.size());
  write_file_atomic(path, out);
}

}  // namespace ii
