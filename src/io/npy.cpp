#include "io/npy.h"

#include <cstring>
#include <limits>
#include <optional>
#include <string_view>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/error.h"
#include "common/files.h"
#include "io/byte_reader.h"

namespace ii {

namespace fs = std::filesystem;

size_t npy_item_size(const std::string& dtype) {
  if (dtype == "b1" || dtype == "i1" || dtype == "u1") return 1;
  if (dtype == "i2" || dtype == "u2") return 2;
  if (dtype == "f4" || dtype == "i4" || dtype == "u4") return 4;
  if (dtype == "f8" || dtype == "i8" || dtype == "u8") return 8;
  return 0;
}

namespace {

// Product of the dimensions times the item size, or nullopt when it overflows 64 bits
// (a lying header must not wrap around to a small, plausible size).
std::optional<uint64_t> byte_count(const std::vector<int64_t>& shape, size_t item) {
  for (int64_t d : shape)
    if (d == 0) return 0;
  uint64_t n = item;
  for (int64_t d : shape)
    if (__builtin_mul_overflow(n, static_cast<uint64_t>(d), &n)) return std::nullopt;
  return n;
}

std::string shape_text(const std::vector<int64_t>& shape) {
  std::string s = fmt::format("{}", fmt::join(shape, ", "));
  if (shape.size() == 1) s += ",";
  return "(" + s + ")";
}

// The header is a Python dict literal, e.g. {'descr': '<f8', 'fortran_order': False,
// 'shape': (20, 17), }. numpy writes exactly these three keys; a small strict parser is
// safer than evaluating or pattern-matching it.
struct NpyHeader {
  std::optional<std::string> descr;
  std::optional<bool> fortran;
  std::optional<std::vector<int64_t>> shape;
};

class HeaderParser {
 public:
  HeaderParser(std::string_view text, const fs::path& path) : s_(text), path_(path) {}

  NpyHeader parse() {
    NpyHeader h;
    skip_ws();
    expect('{');
    while (true) {
      skip_ws();
      if (peek() == '}') {
        ++pos_;
        break;
      }
      const size_t key_pos = pos_;  // errors about a key point at the key
      const std::string key = parse_string("a quoted key");
      skip_ws();
      expect(':');
      skip_ws();
      if (key == "descr") {
        if (h.descr) bad("'descr' appears twice", key_pos);
        if (peek() == '[') fail_file(path_, "structured dtypes are not supported (header {})", quoted());
        h.descr = parse_string("a quoted dtype");
      } else if (key == "fortran_order") {
        if (h.fortran) bad("'fortran_order' appears twice", key_pos);
        h.fortran = parse_bool();
      } else if (key == "shape") {
        if (h.shape) bad("'shape' appears twice", key_pos);
        h.shape = parse_shape();
      } else {
        bad(fmt::format("unexpected key '{}'", key), key_pos);
      }
      skip_ws();
      if (peek() == ',') {
        ++pos_;
      } else if (peek() != '}') {
        bad("expected ',' or '}'");
      }
    }
    skip_ws();
    if (pos_ != s_.size()) bad("text after the closing '}'");
    return h;
  }

 private:
  [[noreturn]] void bad(const std::string& what, std::optional<size_t> at = std::nullopt) const {
    fail_file(path_, "malformed .npy header: {} at character {} of {}", what, at.value_or(pos_), quoted());
  }
  std::string quoted() const {
    std::string t(s_.substr(0, 200));
    while (!t.empty() && (t.back() == ' ' || t.back() == '\n')) t.pop_back();
    return "\"" + t + (s_.size() > 200 ? "...\"" : "\"");
  }
  char peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }
  void skip_ws() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\n' || s_[pos_] == '\r')) ++pos_;
  }
  void expect(char c) {
    if (peek() != c) bad(fmt::format("expected '{}'", c));
    ++pos_;
  }
  std::string parse_string(const char* what) {
    const char q = peek();
    if (q != '\'' && q != '"') bad(fmt::format("expected {}", what));
    const size_t end = s_.find(q, pos_ + 1);
    if (end == std::string_view::npos) bad("unterminated string");
    std::string out(s_.substr(pos_ + 1, end - pos_ - 1));
    if (out.find('\\') != std::string::npos) bad("escape sequences are not supported");
    pos_ = end + 1;
    return out;
  }
  bool parse_bool() {
    if (s_.substr(pos_, 4) == "True") {
      pos_ += 4;
      return true;
    }
    if (s_.substr(pos_, 5) == "False") {
      pos_ += 5;
      return false;
    }
    bad("expected True or False");
  }
  std::vector<int64_t> parse_shape() {
    std::vector<int64_t> shape;
    expect('(');
    while (true) {
      skip_ws();
      if (peek() == ')') {
        ++pos_;
        return shape;
      }
      if (peek() == '-') bad("negative dimension");
      if (peek() < '0' || peek() > '9') bad("expected a dimension");
      const size_t start = pos_;
      uint64_t v = 0;
      while (peek() >= '0' && peek() <= '9') {
        v = v * 10 + static_cast<uint64_t>(peek() - '0');
        if (v > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) bad("dimension too large", start);
        ++pos_;
      }
      if (peek() == 'L') ++pos_;  // Python 2 long literal in old files
      shape.push_back(static_cast<int64_t>(v));
      skip_ws();
      if (peek() == ',') ++pos_;
      else if (peek() != ')') bad("expected ',' or ')' in shape");
    }
  }

  std::string_view s_;
  size_t pos_ = 0;
  const fs::path& path_;
};

// Maps a numpy descr ('<f8', '|u1', ...) to the canonical dtype, refusing what we cannot read.
std::string canonical_dtype(const std::string& descr, const fs::path& path) {
  if (descr.find('O') != std::string::npos)
    fail_file(path, "unsupported dtype '{}' (object arrays and pickles are refused)", descr);
  if (descr.size() < 2) fail_file(path, "unsupported dtype '{}'", descr);
  const char order = descr[0];
  const std::string dtype = descr.substr(1);
  const size_t item = npy_item_size(dtype);
  if ((order != '<' && order != '>' && order != '|' && order != '=') || item == 0)
    fail_file(path, "unsupported dtype '{}' (numeric little-endian dtypes only: f4 f8 i1 i2 i4 i8 u1 u2 u4 u8 b1)", descr);
  if (item > 1 && order == '>') fail_file(path, "big-endian dtype '{}' is not supported", descr);
  // '|' means "byte order not applicable", which numpy uses only for one-byte types.
  if (item > 1 && order == '|') fail_file(path, "dtype '{}' has no byte order", descr);
  return dtype;
}

// Reorders a Fortran-order buffer (first index fastest) into C order (last index fastest).
std::vector<uint8_t> fortran_to_c(const std::vector<uint8_t>& in, const std::vector<int64_t>& shape, size_t item) {
  const size_t n = in.size() / item;
  std::vector<uint8_t> out(in.size());
  std::vector<int64_t> idx(shape.size(), 0);
  for (size_t f = 0; f < n; ++f) {
    size_t c = 0;
    for (size_t d = 0; d < shape.size(); ++d) c = c * static_cast<size_t>(shape[d]) + static_cast<size_t>(idx[d]);
    std::memcpy(&out[c * item], &in[f * item], item);
    for (size_t d = 0; d < shape.size(); ++d) {
      if (++idx[d] < shape[d]) break;
      idx[d] = 0;
    }
  }
  return out;
}

template <typename T>
std::vector<T> convert(const NpyArray& a) {
  const size_t item = npy_item_size(a.dtype);
  if (item == 0) fail("npy array: unknown dtype '{}'", a.dtype);
  const auto bytes = byte_count(a.shape, item);
  if (!bytes || *bytes != a.data.size())
    fail("npy array: {} data bytes do not match shape {} of {}", a.data.size(), shape_text(a.shape), a.dtype);
  const size_t n = a.data.size() / item;
  std::vector<T> out(n);
  auto load = [&](auto tag) {
    using S = decltype(tag);
    for (size_t i = 0; i < n; ++i) {
      S v;
      std::memcpy(&v, a.data.data() + i * sizeof(S), sizeof(S));
      out[i] = static_cast<T>(v);
    }
  };
  const std::string& t = a.dtype;
  if (t == "f4") load(float{});
  else if (t == "f8") load(double{});
  else if (t == "i1") load(int8_t{});
  else if (t == "i2") load(int16_t{});
  else if (t == "i4") load(int32_t{});
  else if (t == "i8") load(int64_t{});
  else if (t == "u1") load(uint8_t{});
  else if (t == "u2") load(uint16_t{});
  else if (t == "u4") load(uint32_t{});
  else if (t == "u8") load(uint64_t{});
  else  // b1: any non-zero byte is true
    for (size_t i = 0; i < n; ++i) out[i] = a.data[i] ? T(1) : T(0);
  return out;
}

}  // namespace

int64_t NpyArray::numel() const {
  int64_t n = 1;
  for (int64_t s : shape) n *= s;
  return n;
}

std::vector<double> NpyArray::as_double() const { return convert<double>(*this); }
std::vector<float> NpyArray::as_float() const { return convert<float>(*this); }

NpyArray read_npy(const fs::path& path) {
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  if (bytes.size() < 6 || std::memcmp(bytes.data(), "\x93NUMPY", 6) != 0)
    fail_file(path, "not a .npy file (missing \\x93NUMPY magic)");
  ByteReader r(bytes.data(), bytes.size(), path);
  r.skip(6, "magic");
  const uint8_t major = r.read<uint8_t>("version");
  const uint8_t minor = r.read<uint8_t>("version");
  if ((major != 1 && major != 2 && major != 3) || minor != 0)
    fail_file(path, "unsupported .npy format version {}.{} (1.0, 2.0 and 3.0 are read)", major, minor);
  const size_t header_len = major == 1 ? r.read<uint16_t>("header length") : r.read<uint32_t>("header length");
  const std::string text = r.read_string(header_len, "header");
  const NpyHeader h = HeaderParser(text, path).parse();
  if (!h.descr) fail_file(path, "header has no 'descr' entry");
  if (!h.fortran) fail_file(path, "header has no 'fortran_order' entry");
  if (!h.shape) fail_file(path, "header has no 'shape' entry");

  NpyArray a;
  a.dtype = canonical_dtype(*h.descr, path);
  a.shape = *h.shape;
  const size_t item = npy_item_size(a.dtype);
  const auto need = byte_count(a.shape, item);
  if (!need || *need != r.remaining())
    fail_file(path, "data size mismatch: shape {} of {} needs {} bytes, the file has {}", shape_text(a.shape),
              *h.descr, need ? fmt::format("{}", *need) : std::string("more than 2^64"), r.remaining());
  a.data.assign(r.current(), r.current() + *need);
  if (*h.fortran && a.shape.size() > 1) a.data = fortran_to_c(a.data, a.shape, item);
  return a;
}

void write_npy(const fs::path& path, const NpyArray& a) {
  const size_t item = npy_item_size(a.dtype);
  if (item == 0) fail_file(path, "cannot write dtype '{}'", a.dtype);
  for (int64_t d : a.shape)
    if (d < 0) fail_file(path, "cannot write shape {} with a negative dimension", shape_text(a.shape));
  const auto need = byte_count(a.shape, item);
  if (!need || *need != a.data.size())
    fail_file(path, "array data ({} bytes) does not match shape {} of {}", a.data.size(), shape_text(a.shape), a.dtype);
  const char order = item == 1 ? '|' : '<';
  std::string header =
      fmt::format("{{'descr': '{}{}', 'fortran_order': False, 'shape': {}, }}", order, a.dtype, shape_text(a.shape));
  // Version 1.0 has a 2-byte header length; numpy switches to 2.0 (4 bytes) past that.
  const bool v2 = header.size() + 1 + 64 > 65535;
  const size_t prefix = v2 ? 12 : 10;  // magic, version, header length
  // Pad with spaces so that the data starts at a multiple of 64 bytes (numpy's alignment).
  header.append((64 - (prefix + header.size() + 1) % 64) % 64, ' ');
  header.push_back('\n');
  std::string out(v2 ? "\x93NUMPY\x02\x00" : "\x93NUMPY\x01\x00", 8);
  if (v2) {
    const uint32_t len = static_cast<uint32_t>(header.size());
    out.append(reinterpret_cast<const char*>(&len), 4);
  } else {
    const uint16_t len = static_cast<uint16_t>(header.size());
    out.append(reinterpret_cast<const char*>(&len), 2);
  }
  out += header;
  out.append(reinterpret_cast<const char*>(a.data.data()), a.data.size());
  write_file_atomic(path, out);
}

void write_npy(const fs::path& path, const std::vector<double>& values, std::vector<int64_t> shape) {
  NpyArray a;
  a.dtype = "f8";
  a.shape = std::move(shape);
  a.data.resize(values.size() * sizeof(double));
  if (!values.empty()) std::memcpy(a.data.data(), values.data(), a.data.size());
  write_npy(path, a);
}

}  // namespace ii
