#include "tensor/tensor_taker.h"

#include <algorithm>

#include <fmt/ranges.h>

#include "common/error.h"

namespace ii {

std::string shape_text(at::IntArrayRef shape) {
  std::vector<std::string> parts;
  for (int64_t s : shape) parts.push_back(std::to_string(s));
  return "[" + fmt::format("{}", fmt::join(parts, ", ")) + "]";
}

TensorTaker::TensorTaker(TensorMap tensors, std::filesystem::path file, std::string network, std::string module)
    : tensors_(std::move(tensors)), file_(std::move(file)), network_(std::move(network)), module_(std::move(module)) {}

at::IntArrayRef TensorTaker::shape(const std::string& key) const {
  const auto it = tensors_.find(key);
  if (it == tensors_.end()) fail("{}: the tensor {} is missing ({} has it)", file_.string(), key, network_);
  return it->second.sizes();
}

int64_t TensorTaker::size(at::IntArrayRef shape, size_t dim) const {
  if (shape.size() <= dim)
    fail("{}: a tensor of shape {} where {} dimensions were expected", file_.string(), shape_text(shape), dim + 1);
  return shape[dim];
}

torch::Tensor TensorTaker::take(const std::string& key, std::vector<int64_t> shape) {
  const auto it = tensors_.find(key);
  if (it == tensors_.end()) fail("{}: the tensor {} is missing ({} has it)", file_.string(), key, network_);
  const torch::Tensor& t = it->second;
  if (!shape.empty()) {
    bool ok = static_cast<size_t>(t.dim()) == shape.size();
    for (size_t i = 0; ok && i < shape.size(); ++i) ok = shape[i] < 0 || shape[i] == t.size(static_cast<int64_t>(i));
    if (!ok) fail("{}: {} has shape {}, expected {}", file_.string(), key, shape_text(t.sizes()), shape_text(shape));
  }
  if (!t.is_floating_point())
    fail("{}: {} holds {}, not floating-point numbers", file_.string(), key, std::string(c10::toString(t.scalar_type())));
  used_.insert(key);
  torch::Tensor f = t.to(torch::kFloat).contiguous();
  if (!torch::isfinite(f).all().item<bool>()) fail("{}: {} holds a NaN or an infinity", file_.string(), key);
  return f;
}

int64_t TensorTaker::count(const std::string& prefix, const std::string& suffix) const {
  int64_t n = 0;
  while (has(prefix + std::to_string(n) + suffix)) ++n;
  return n;
}

void TensorTaker::check_all_used(const std::vector<std::string>& ignored) const {
  std::vector<std::string> left;
  for (const auto& [key, t] : tensors_) {
    if (used_.count(key)) continue;
    bool skip = false;
    for (const std::string& p : ignored) skip = skip || key.rfind(p, 0) == 0 || key.find(p) != std::string::npos;
    if (!skip) left.push_back(key);
  }
  if (!left.empty())
    fail("{}: {} tensor(s) that no {} has: {}{}", file_.string(), left.size(), module_,
         fmt::join(left.begin(), left.begin() + static_cast<std::ptrdiff_t>(std::min<size_t>(left.size(), 5)), ", "),
         left.size() > 5 ? ", ..." : "");
}

}  // namespace ii
