#pragma once
#include <chrono>

namespace ii {

// Wall-clock timing of pipeline stages, in milliseconds.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
  }
  // Milliseconds since construction or the previous lap.
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double d = std::chrono::duration<double, std::milli>(now - start_).count();
    start_ = now;
    return d;
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace ii
