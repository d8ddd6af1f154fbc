#pragma once
// Bounds-checked little-endian cursor over an in-memory file. Every binary parser reads
// through it, so a truncated or lying file becomes a clear Error naming the file and the
// byte offset instead of an out-of-bounds read.
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <type_traits>

#include "common/error.h"

namespace ii {

class ByteReader {
 public:
  ByteReader(const uint8_t* data, size_t size, std::filesystem::path file)
      : data_(data), size_(size), file_(std::move(file)) {}

  size_t position() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }
  size_t size() const { return size_; }
  const std::filesystem::path& file() const { return file_; }
  const uint8_t* current() const { return data_ + pos_; }

  void require(size_t n, const char* what) const {
    if (n > remaining())
      fail_file(file_, "truncated file: needs {} more bytes for {} at byte {}, only {} left", n,
                what, pos_, remaining());
  }
  void skip(size_t n, const char* what) {
    require(n, what);
    pos_ += n;
  }
  void seek(size_t pos, const char* what) {
    if (pos > size_) fail_file(file_, "offset {} for {} is past the end of the file ({} bytes)", pos, what, size_);
    pos_ = pos;
  }

  template <typename T>
  T read(const char* what) {
    static_assert(std::is_trivially_copyable_v<T>, "plain values only");
    require(sizeof(T), what);
    T value;
    std::memcpy(&value, data_ + pos_, sizeof(T));  // host is little-endian (x86-64, aarch64)
    pos_ += sizeof(T);
    return value;
  }

  void read_bytes(void* dst, size_t n, const char* what) {
    require(n, what);
    if (n) std::memcpy(dst, data_ + pos_, n);
    pos_ += n;
  }

  std::string read_string(size_t n, const char* what) {
    require(n, what);
    std::string s(reinterpret_cast<const char*>(data_ + pos_), n);
    pos_ += n;
    return s;
  }

  // Reads up to and including a NUL byte (COLMAP image names).
  std::string read_cstring(const char* what) {
    const void* end = std::memchr(data_ + pos_, 0, remaining());
    if (!end) fail_file(file_, "truncated file: unterminated {} at byte {}", what, pos_);
    const size_t n = static_cast<const uint8_t*>(end) - (data_ + pos_);
    std::string s(reinterpret_cast<const char*>(data_ + pos_), n);
    pos_ += n + 1;
    return s;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  std::filesystem::path file_;
};

}  // namespace ii
