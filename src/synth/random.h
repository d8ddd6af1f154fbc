#pragma once
// The synthetic generator's own random numbers. std::mt19937_64's output sequence is fixed
// by the C++ standard, but the standard distributions are not (libstdc++ and libc++ draw
// differently), so the conversions to uniform and normal values are written here: a scene
// is the same bytes for a seed on every platform. Never touches torch's global generator.
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "common/error.h"

namespace ii::synth {

// SplitMix64 finaliser over (seed, stream): independent seeds for scene k of a run, or for
// one part of a scene, so that adding draws to one part does not shift the others.
inline uint64_t mix_seed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9E3779B97F4A7C15ull * (stream + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

class SynthRng {
 public:
  explicit SynthRng(uint64_t seed) : engine_(seed) {}

  uint64_t bits() { return engine_(); }
  // Uniform in [0, 1), 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [lo, hi] (inclusive).
  int integer(int lo, int hi) {
    if (hi < lo) fail("SynthRng::integer: empty range [{}, {}]", lo, hi);
    const uint64_t span = static_cast<uint64_t>(hi - lo) + 1;
    return lo + static_cast<int>(engine_() % span);  // bias < 2^-50 for the small spans used
  }
  // Standard normal (Box-Muller, one value per call).
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }
  bool chance(double p) { return uniform() < p; }
  template <typename T>
  const T& pick(const std::vector<T>& items) {
    if (items.empty()) fail("SynthRng::pick: empty list");
    return items[static_cast<size_t>(integer(0, static_cast<int>(items.size()) - 1))];
  }
  // Index drawn with the given non-negative weights.
  int weighted(const std::vector<double>& weights) {
    double total = 0;
    for (double w : weights) total += w;
    double r = uniform() * total;
    for (size_t i = 0; i < weights.size(); ++i) {
      if (r < weights[i]) return static_cast<int>(i);
      r -= weights[i];
    }
    return static_cast<int>(weights.size()) - 1;
  }

 private:
  std::mt19937_64 engine_;
};

}  // namespace ii::synth
