#pragma once
// A published checkpoint's tensors handed out by key to the code that builds a network from
// them: each shape checked as it is taken, floats only and finite, and at the end whatever no
// module took named. Errors name the file, the key and the network the file should hold.
#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "tensor/tensor_file.h"

namespace ii {

// "[2, 3, 4]"
std::string shape_text(at::IntArrayRef shape);

class TensorTaker {
 public:
  // `network` names what such a file holds, in errors: "a SAM or MobileSAM checkpoint" (has it),
  // and `module` its parts: "SAM or MobileSAM module" (no ... has).
  TensorTaker(TensorMap tensors, std::filesystem::path file, std::string network, std::string module);

  bool has(const std::string& key) const { return tensors_.count(key) > 0; }
  at::IntArrayRef shape(const std::string& key) const;
  // shape[dim], an Error when it has fewer dimensions.
  int64_t size(at::IntArrayRef shape, size_t dim) const;
  // The tensor as float; `shape` entries of -1 are any size.
  torch::Tensor take(const std::string& key, std::vector<int64_t> shape = {});
  // How many of prefix + 0 + suffix, prefix + 1 + suffix, ... there are in a row.
  int64_t count(const std::string& prefix, const std::string& suffix) const;
  // Every tensor taken, but those whose key starts with or holds one of `ignored`.
  void check_all_used(const std::vector<std::string>& ignored) const;
  const std::filesystem::path& file() const { return file_; }

 private:
  TensorMap tensors_;
  std::filesystem::path file_;
  std::string network_, module_;
  std::set<std::string> used_;
};

}  // namespace ii
