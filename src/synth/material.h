#pragma once
// Procedural surface colours for the synthetic scenes: lattice value noise, its fractal sum,
// and patterns (wood planks, tiles, bricks, stripes, ...) evaluated at a surface point.
// Everything is a pure function of its arguments and the material's seed.
#include <cstdint>

#include <Eigen/Core>

namespace ii::synth {

using Rgb = Eigen::Vector3f;

// Hash of two integers and a seed to [0, 1).
float hash01(int64_t a, int64_t b, uint32_t seed);
// Smooth lattice value noise in [0, 1] (trilinear with smoothstep weights), unit cells.
float value_noise(const Eigen::Vector3d& p, uint32_t seed);
// Sum of `octaves` value noises at doubling frequency and halving amplitude, in [0, 1].
float fbm(const Eigen::Vector3d& p, uint32_t seed, int octaves = 4);

// h in [0, 1) turns, s and v in [0, 1].
Rgb hsv(double h, double s, double v);

enum class Pattern {
  solid,    // base with faint noise
  noise,    // blotches mixing base and accent
  wood,     // planks along u, width `scale`, staggered joints, grain
  tiles,    // square tiles of `scale` with accent grout
  checker,  // alternating base / accent squares of `scale`
  bricks,   // running bond, bricks `scale` long, accent mortar
  stripes,  // bands of width `scale` along u
  dots,     // accent dots on a grid of `scale`
  marble,   // base with accent veins
  fabric,   // fine weave
  panels,   // horizontal panel lines every `scale` (cabinet fronts)
  canvas,   // colourful abstract painting
  sky,      // window view: sky gradient with clouds (v = height)
};

struct Material {
  Pattern pattern = Pattern::solid;
  Rgb base{0.7f, 0.7f, 0.7f};
  Rgb accent{0.3f, 0.3f, 0.3f};
  double scale = 0.2;       // characteristic pattern size, metres
  double variation = 0.08;  // amplitude of the fine noise on top of the pattern
  uint32_t seed = 0;
  double opacity = 0.97;  // of each Gaussian of the surface
  bool lit = true;        // false: emissive (windows), no shading

  // Colour at surface coordinates (u, v) in metres and world point p, in [0, 1].
  Rgb colour(double u, double v, const Eigen::Vector3d& p) const;
};

}  // namespace ii::synth
