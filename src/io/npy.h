#pragma once
// NumPy .npy arrays (format versions 1.0, 2.0 and 3.0): little-endian numeric dtypes, C or
// Fortran order (Fortran is reordered to C on read). Big-endian data, object arrays (which
// numpy stores as pickles), strings and structured dtypes are refused.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ii {

struct NpyArray {
  // Canonical dtype without byte-order mark: "f4", "f8", "i1", "i2", "i4", "i8", "u1", "u2",
  // "u4", "u8", "b1".
  std::string dtype;
  std::vector<int64_t> shape;  // empty = a scalar (one element)
  std::vector<uint8_t> data;   // little-endian, C order

  int64_t numel() const;
  // Element-wise conversions; b1 gives 0 or 1. Throw Error when dtype is unknown or data
  // does not match the shape.
  std::vector<double> as_double() const;
  std::vector<float> as_float() const;
};

// Bytes per element of a canonical dtype, 0 when unknown.
size_t npy_item_size(const std::string& dtype);

NpyArray read_npy(const std::filesystem::path& path);
// Writes format 1.0 (2.0 when the header needs more than 64 KiB), header padded so the data
// starts on a 64-byte boundary as numpy does. Atomic.
void write_npy(const std::filesystem::path& path, const NpyArray& array);
// float64 array of the given shape; values.size() must equal the product of the shape.
void write_npy(const std::filesystem::path& path, const std::vector<double>& values,
               std::vector<int64_t> shape);

}  // namespace ii
