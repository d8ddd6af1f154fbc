#pragma once
// One error type for everything that reads outside input: the message always names the
// file (or argument) and what is wrong, so the CLI can print it as is and exit non-zero.
#include <filesystem>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace ii {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Throws Error("<file>: <problem>").
template <typename... Args>
[[noreturn]] void fail_file(const std::filesystem::path& file, fmt::format_string<Args...> f,
                            Args&&... args) {
  throw Error(file.string() + ": " + fmt::format(f, std::forward<Args>(args)...));
}

template <typename... Args>
[[noreturn]] void fail(fmt::format_string<Args...> f, Args&&... args) {
  throw Error(fmt::format(f, std::forward<Args>(args)...));
}

}  // namespace ii
