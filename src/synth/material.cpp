#include "synth/material.h"

#include <algorithm>
#include <cmath>

namespace ii::synth {

namespace {

uint64_t hash64(uint64_t x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdull;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ull;
  x ^= x >> 33;
  return x;
}

float lattice(int64_t x, int64_t y, int64_t z, uint32_t seed) {
  uint64_t h = hash64(static_cast<uint64_t>(x) * 0x9E3779B97F4A7C15ull ^ static_cast<uint64_t>(seed));
  h = hash64(h ^ static_cast<uint64_t>(y) * 0xC2B2AE3D27D4EB4Full);
  h = hash64(h ^ static_cast<uint64_t>(z) * 0x165667B19E3779F9ull);
  return static_cast<float>(h >> 40) * (1.0f / 16777216.0f);
}

double smooth(double t) { return t * t * (3.0 - 2.0 * t); }
double fract(double x) { return x - std::floor(x); }
Rgb mix(const Rgb& a, const Rgb& b, double t) { return a + (b - a) * static_cast<float>(t); }
double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return smooth(t);
}

}  // namespace

float hash01(int64_t a, int64_t b, uint32_t seed) { return lattice(a, b, 0x5bd1e995, seed); }

float value_noise(const Eigen::Vector3d& p, uint32_t seed) {
  const double fx = std::floor(p.x()), fy = std::floor(p.y()), fz = std::floor(p.z());
  const int64_t ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy), iz = static_cast<int64_t>(fz);
  const double tx = smooth(p.x() - fx), ty = smooth(p.y() - fy), tz = smooth(p.z() - fz);
  double acc = 0;
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        const double w = (dx ? tx : 1 - tx) * (dy ? ty : 1 - ty) * (dz ? tz : 1 - tz);
        acc += w * lattice(ix + dx, iy + dy, iz + dz, seed);
      }
  return static_cast<float>(acc);
}

float fbm(const Eigen::Vector3d& p, uint32_t seed, int octaves) {
  double sum = 0, amplitude = 0.5, norm = 0;
  Eigen::Vector3d q = p;
  for (int o = 0; o < octaves; ++o) {
    sum += amplitude * value_noise(q, seed + 1013u * static_cast<uint32_t>(o));
    norm += amplitude;
    amplitude *= 0.5;
    q = q * 2.03 + Eigen::Vector3d(17.1, 5.3, 11.7);  // offset: octaves share no lattice points
  }
  return static_cast<float>(sum / norm);
}

Rgb hsv(double h, double s, double v) {
  h = fract(h) * 6.0;
  const int sector = static_cast<int>(h) % 6;
  const double f = h - std::floor(h);
  const double p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  switch (sector) {
    case 0:
      return Rgb(v, t, p);
    case 1:
      return Rgb(q, v, p);
    case 2:
      return Rgb(p, v, t);
    case 3:
      return Rgb(p, q, v);
    case 4:
      return Rgb(t, p, v);
    default:
      return Rgb(v, p, q);
  }
}

Rgb Material::colour(double u, double v, const Eigen::Vector3d& p) const {
  const double s = std::max(scale, 1e-4);
  Rgb c = base;
  switch (pattern) {
    case Pattern::solid:
      break;
    case Pattern::noise:
      c = mix(base, accent, smoothstep(0.3, 0.7, fbm(p / s, seed + 7, 4)));
      break;
    case Pattern::wood: {
      const double row = std::floor(v / s);
      const double plank_length = 6.0 * s;
      const double shifted = u + hash01(static_cast<int64_t>(row), 1, seed) * plank_length;
      const double column = std::floor(shifted / plank_length);
      const double tint = hash01(static_cast<int64_t>(row), static_cast<int64_t>(column), seed) - 0.5;
      // Grain: lines along the plank, bent by noise.
      const double bend = fbm(Eigen::Vector3d(shifted * 1.5, v * 12.0 / s, row), seed + 3, 3);
      const double grain = 0.5 + 0.5 * std::sin(2.0 * M_PI * (2.0 * v / s + 3.0 * bend));
      c = mix(base, accent, 0.25 * grain + 0.35 * (tint + 0.5));
      const double fv = fract(v / s), fu = fract(shifted / plank_length);
      if (fv < 0.04 || fv > 0.985 || fu < 0.008) c *= 0.55f;  // seams between planks
      break;
    }
    case Pattern::tiles:
    case Pattern::checker: {
      const double cu = std::floor(u / s), cv = std::floor(v / s);
      const double fu = fract(u / s), fv = fract(v / s);
      const double tint = hash01(static_cast<int64_t>(cu), static_cast<int64_t>(cv), seed) - 0.5;
      if (pattern == Pattern::checker) c = (static_cast<int64_t>(cu + cv) & 1) ? accent : base;
      c *= static_cast<float>(1.0 + 0.12 * tint);
      const double grout = 0.035;
      if (fu < grout || fv < grout) c = pattern == Pattern::tiles ? accent : Rgb(c * 0.6f);
      break;
    }
    case Pattern::bricks: {
      const double h = 0.4 * s;
      const double row = std::floor(v / h);
      const double shifted = u / s + (static_cast<int64_t>(row) & 1 ? 0.5 : 0.0);
      const double col = std::floor(shifted);
      const double tint = hash01(static_cast<int64_t>(row), static_cast<int64_t>(col), seed) - 0.5;
      c = base * static_cast<float>(1.0 + 0.35 * tint);
      if (fract(v / h) < 0.12 || fract(shifted) < 0.045) c = accent;
      break;
    }
    case Pattern::stripes: {
      const double t = fract(u / s);
      c = t < 0.5 ? base : accent;
      if (std::abs(t - 0.5) < 0.03 || t < 0.03) c = mix(base, accent, 0.5) * 0.85f;
      break;
    }
    case Pattern::dots: {
      const double fu = fract(u / s) - 0.5,
                   fv = fract(v / s + 0.5 * (static_cast<int64_t>(std::floor(u / s)) & 1)) - 0.5;
      if (fu * fu + fv * fv < 0.2 * 0.2) c = accent;
      break;
    }
    case Pattern::marble: {
      const double vein = std::abs(std::sin((u + 0.6 * v) / s * 2.0 + 6.0 * fbm(p / s, seed, 5)));
      c = mix(accent, base, smoothstep(0.0, 0.25, vein));
      break;
    }
    case Pattern::fabric: {
      const double f = 2.0 * M_PI / s;
      const double weave = 0.5 + 0.25 * (std::sin(u * f) + std::sin(v * f));
      c = mix(base, accent, 0.25 * weave + 0.4 * fbm(p * (4.0 / s), seed, 3));
      break;
    }
    case Pattern::panels: {
      const double t = fract(v / s);
      if (t < 0.03) c = accent;
      break;
    }
    case Pattern::canvas: {
      const Eigen::Vector3d q(u / s, v / s, seed % 97);
      const double a = fbm(q, seed, 4), b = fbm(q * 1.7, seed + 11, 3);
      const Rgb third = hsv(hash01(seed, 3, seed) + 0.33, 0.7, 0.9);
      c = mix(mix(base, accent, smoothstep(0.35, 0.65, a)), third, smoothstep(0.55, 0.75, b));
      break;
    }
    case Pattern::sky: {
      const double t = std::clamp(v / s, 0.0, 1.0);
      c = mix(accent, base, t);  // accent at the bottom (horizon), base at the top
      const double cloud = smoothstep(0.5, 0.8, fbm(Eigen::Vector3d(u * 3.0, v * 6.0, seed % 31), seed, 4));
      c = mix(c, Rgb(1.f, 1.f, 1.f), 0.8 * cloud);
      break;
    }
  }
  if (variation > 0) {
    const double n = fbm(p * 9.0, seed + 101, 3) - 0.5;
    c *= static_cast<float>(1.0 + 2.0 * variation * n);
  }
  return c.cwiseMax(0.f).cwiseMin(1.f);
}

}  // namespace ii::synth
