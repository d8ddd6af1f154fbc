#pragma once
// NumPy .npy arrays (format 1.0/2.0/3.0), little-endian numeric dtypes, C or Fortran order.
// Object arrays (pickles) are refused.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ii {

struct NpyArray {
  std::string dtype;            // canonical: "f4", "f8", "i4", "i8", "u1", "b1"
  std::vector<int64_t> shape;
  std::vector<uint8_t> data;    // C order

  int64_t numel() const;
  std::vector<double> as_double() const;
  std::vector<float> as_float() const;
};

NpyArray read_npy(const std::filesystem::path& path);
void write_npy(const std::filesystem::path& path, const NpyArray& array);
void write_npy(const std::filesystem::path& path, const std::vector<double>& values, std::vector<int64_t> shape);

}  // namespace ii
