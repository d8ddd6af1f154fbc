#pragma once
// IEEE half-precision bits to float, exactly (subnormals, infinities and NaN payloads kept): the
// 16-bit floats of .pth, safetensors and SPZ files.
#include <cstdint>
#include <cstring>

namespace ii {

inline float half_to_float(uint16_t h) {
  const uint32_t sign = static_cast<uint32_t>(h & 0x8000u) << 16;
  const uint32_t exp = (h >> 10) & 0x1fu, man = h & 0x3ffu;
  uint32_t bits;
  if (exp == 0) {
    if (man == 0) {
      bits = sign;
    } else {  // subnormal half: shift the mantissa up until it is normalised
      uint32_t m = man, shifts = 0;
      while ((m & 0x400u) == 0) {
        m <<= 1;
        ++shifts;
      }
      bits = sign | ((127 - 15 + 1 - shifts) << 23) | ((m & 0x3ffu) << 13);
    }
  } else if (exp == 31) {
    bits = sign | 0x7f800000u | (man << 13);  // inf / nan
  } else {
    bits = sign | ((exp + 127 - 15) << 23) | (man << 13);
  }
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

}  // namespace ii
