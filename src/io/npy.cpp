#include "io/npy.h"

#include <cstring>
#include <map>
#include <regex>

#include <fmt/ranges.h>

#include "common/error.h"
#include "common/files.h"
#include "io/byte_reader.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

size_t item_size(const std::string& dtype) {
  static const std::map<std::string, size_t> sizes = {{"f4", 4}, {"f8", 8}, {"i4", 4}, {"i8", 8},
                                                      {"u1", 1}, {"b1", 1}, {"i2", 2}, {"u2", 2}};
  auto it = sizes.find(dtype);
  return it == sizes.end() ? 0 : it->second;
}

template <typename T>
void widen(const NpyArray& a, std::vector<T>& out) {
  const size_t n = static_cast<size_t>(a.numel());
  out.resize(n);
  auto load = [&](auto tag) {
    using S = decltype(tag);
    for (size_t i = 0; i < n; ++i) {
      S v;
      std::memcpy(&v, a.data.data() + i * sizeof(S), sizeof(S));
      out[i] = static_cast<T>(v);
    }
  };
  if (a.dtype == "f4") load(float{});
  else if (a.dtype == "f8") load(double{});
  else if (a.dtype == "i4") load(int32_t{});
  else if (a.dtype == "i8") load(int64_t{});
  else if (a.dtype == "i2") load(int16_t{});
  else if (a.dtype == "u2") load(uint16_t{});
  else load(uint8_t{});  // u1, b1
}

// Reorders a Fortran-order buffer (first index fastest) into C order.
std::vector<uint8_t> fortran_to_c(const std::vector<uint8_t>& in, const std::vector<int64_t>& shape, size_t item) {
  const size_t n = in.size() / item;
  std::vector<uint8_t> out(in.size());
  std::vector<int64_t> idx(shape.size(), 0);
  for (size_t f = 0; f < n; ++f) {
    // f enumerates Fortran order; compute the C-order offset of the same index.
    size_t c = 0;
    for (size_t d = 0; d < shape.size(); ++d) c = c * shape[d] + idx[d];
    std::memcpy(&out[c * item], &in[f * item], item);
    for (size_t d = 0; d < shape.size(); ++d) {
      if (++idx[d] < shape[d]) break;
      idx[d] = 0;
    }
  }
  return out;
}

}  // namespace

int64_t NpyArray::numel() const {
  int64_t n = 1;
  for (int64_t s : shape) n *= s;
  return n;
}

std::vector<double> NpyArray::as_double() const {
  std::vector<double> out;
  widen(*this, out);
  return out;
}

std::vector<float> NpyArray::as_float() const {
  std::vector<float> out;
  widen(*this, out);
  return out;
}

NpyArray read_npy(const fs::path& path) {
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  ByteReader r(bytes.data(), bytes.size(), path);
  if (bytes.size() < 6 || std::memcmp(bytes.data(), "\x93NUMPY", 6) != 0)
    fail_file(path, "not a .npy file (missing \\x93NUMPY magic)");
  r.skip(6, "magic");
  const uint8_t major = r.read<uint8_t>("version"), minor = r.read<uint8_t>("version");
  (void)minor;
  size_t header_len = 0;
  if (major == 1) header_len = r.read<uint16_t>("header length");
  else if (major == 2 || major == 3) header_len = r.read<uint32_t>("header length");
  else fail_file(path, "unsupported .npy format version {}", major);
  const std::string header = r.read_string(header_len, "header");

  static const std::regex descr_re(R"('descr'\s*:\s*'([^']*)')");
  static const std::regex order_re(R"('fortran_order'\s*:\s*(True|False))");
  static const std::regex shape_re(R"('shape'\s*:\s*\(([^)]*)\))");
  std::smatch m;
  if (!std::regex_search(header, m, descr_re)) fail_file(path, "header has no 'descr' entry");
  std::string descr = m[1];
  if (!std::regex_search(header, m, order_re)) fail_file(path, "header has no 'fortran_order' entry");
  const bool fortran = m[1] == "True";
  if (!std::regex_search(header, m, shape_re)) fail_file(path, "header has no 'shape' entry");
  const std::string shape_text = m[1];

  NpyArray a;
  if (descr.size() < 2 || (descr[0] != '<' && descr[0] != '|' && descr[0] != '>'))
    fail_file(path, "unsupported dtype '{}'", descr);
  if (descr[0] == '>' && descr.substr(1) != "u1" && descr.substr(1) != "b1")
    fail_file(path, "big-endian dtype '{}' is not supported", descr);
  a.dtype = descr.substr(1);
  const size_t item = item_size(a.dtype);
  if (item == 0) fail_file(path, "unsupported dtype '{}' (object arrays and pickles are refused)", descr);

  static const std::regex dim_re(R"(\s*(\d+)\s*)");
  size_t pos = 0;
  int64_t numel = 1;
  while (pos < shape_text.size()) {
    const size_t comma = shape_text.find(',', pos);
    const std::string part = shape_text.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos);
    pos = comma == std::string::npos ? shape_text.size() : comma + 1;
    if (part.find_first_not_of(" \t") == std::string::npos) continue;
    std::smatch dm;
    if (!std::regex_match(part, dm, dim_re)) fail_file(path, "malformed shape '({})'", shape_text);
    const long long dim = std::stoll(dm[1]);
    if (dim > (1LL << 40)) fail_file(path, "implausible dimension {} in shape", dim);
    a.shape.push_back(dim);
    numel *= dim;
    if (numel > static_cast<int64_t>(bytes.size())) break;  // checked against the data below
  }
  const uint64_t need = static_cast<uint64_t>(numel) * item;
  if (need != r.remaining())
    fail_file(path, "data size mismatch: shape ({}) of {} needs {} bytes, the file has {}",
              fmt::join(a.shape, ", "), descr, need, r.remaining());
  a.data.assign(r.current(), r.current() + need);
  if (fortran && a.shape.size() > 1) a.data = fortran_to_c(a.data, a.shape, item);
  return a;
}

void write_npy(const fs::path& path, const NpyArray& a) {
  const size_t item = item_size(a.dtype);
  if (item == 0) fail_file(path, "cannot write dtype '{}'", a.dtype);
  if (static_cast<size_t>(a.numel()) * item != a.data.size())
    fail_file(path, "array data does not match its shape");
  const char order = (a.dtype == "u1" || a.dtype == "b1") ? '|' : '<';
  std::string shape = fmt::format("{}", fmt::join(a.shape, ", "));
  if (a.shape.size() == 1) shape += ",";
  std::string header = fmt::format("{{'descr': '{}{}', 'fortran_order': False, 'shape': ({}), }}", order, a.dtype, shape);
  // Pad with spaces so that magic + version + length + header + '\n' is a multiple of 64.
  const size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header.push_back('\n');
  std::string out("\x93NUMPY\x01\x00", 8);
  const uint16_t len = static_cast<uint16_t>(header.size());
  out.append(reinterpret_cast<const char*>(&len), 2);
  out += header;
  out.append(reinterpret_cast<const char*>(a.data.data()), a.data.size());
  write_file_atomic(path, out);
}

void write_npy(const fs::path& path, const std::vector<double>& values, std::vector<int64_t> shape) {
  NpyArray a;
  a.dtype = "f8";
  a.shape = std::move(shape);
  a.data.resize(values.size() * sizeof(double));
  std::memcpy(a.data.data(), values.data(), a.data.size());
  write_npy(path, a);
}

}  // namespace ii
