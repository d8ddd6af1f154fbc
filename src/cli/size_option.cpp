#include "cli/size_option.h"

#include <stdexcept>

#include "common/error.h"

namespace ii::cli {

InputSize parse_size(const std::string& text, const std::string& option) {
  InputSize s;
  const size_t x = text.find('x');
  try {
    size_t used = 0;
    s.width = std::stoi(text.substr(0, x), &used);
    if (used != (x == std::string::npos ? text.size() : x)) throw std::invalid_argument(text);
    s.height = x == std::string::npos ? s.width : std::stoi(text.substr(x + 1), &used);
    if (x != std::string::npos && used != text.size() - x - 1) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    fail("{}: '{}' is not a size (expected N for N x N, or WIDTHxHEIGHT)", option, text);
  }
  if (s.width < 8 || s.height < 8 || s.width > 8192 || s.height > 8192)
    fail("{}: {}x{} is outside 8..8192 pixels", option, s.width, s.height);
  return s;
}

}  // namespace ii::cli
