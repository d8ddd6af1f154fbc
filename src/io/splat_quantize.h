#pragma once
// What the compressed splat formats (compressed PLY, SPZ, SOG) share: rotations stored as their
// three smallest quaternion components, and 8-bit opacities.
#include <cmath>
#include <cstdint>

namespace ii::splat_quantize {

// A rotation normalised with its largest component made positive (q and -q are the same
// rotation), so that the largest can be left out and recovered from the unit norm.
struct SmallestThree {
  double q[4];      // normalised (w, x, y, z), q[largest] >= 0
  int largest = 0;  // index of the component of largest magnitude
};

// From (w, x, y, z); a zero or non-finite quaternion becomes the identity.
inline SmallestThree smallest_three(const float* wxyz) {
  SmallestThree r;
  double norm = 0;
  for (int a = 0; a < 4; ++a) norm += double(wxyz[a]) * wxyz[a];
  norm = std::sqrt(norm);
  const bool usable = norm > 0 && std::isfinite(norm);
  for (int a = 0; a < 4; ++a) r.q[a] = usable ? wxyz[a] / norm : (a == 0 ? 1.0 : 0.0);
  for (int a = 1; a < 4; ++a)
    if (std::abs(r.q[a]) > std::abs(r.q[r.largest])) r.largest = a;
  if (r.q[r.largest] < 0)
    for (double& v : r.q) v = -v;
  return r;
}

// An 8-bit opacity (255 = 1) as a logit; 0 and 255 stand for opacities beyond the 8-bit range:
// ±40, as PlayCanvas decodes compressed PLY.
inline float opacity_logit_of_byte(uint8_t byte) {
  if (byte == 0) return -40.f;
  if (byte == 255) return 40.f;
  const double alpha = byte / 255.0;
  return static_cast<float>(std::log(alpha / (1 - alpha)));
}

}  // namespace ii::splat_quantize
