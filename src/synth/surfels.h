#pragma once
// Surfaces made of flat 3D Gaussians ("surfels"): a builder that collects activated Gaussian
// parameters, a simple baked lighting model, and samplers for the primitives the synthetic
// scenes are built from (rectangles, boxes, surfaces of revolution, ellipsoids). Each
// surface is covered by a jittered grid of Gaussians `spacing` metres apart, flat along the
// surface normal, coloured by a Material and shaded by the Lighting.
#include <functional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "render/rasterizer.h"
#include "synth/material.h"
#include "synth/random.h"

namespace ii::synth {

// Every Gaussian of a synthetic scene has opacity at most this. The rasterizer stops a pixel
// before the splat that would bring its transmittance to <= 1e-4; with alpha <= 0.98 that can
// only happen once the transmittance is already below 1e-4 / 0.02 = 0.005, which bounds how
// much removing a Gaussian can change a pixel it does not cover (see synth_views.h).
inline constexpr double kMaxOpacity = 0.98;

class GaussianBuilder {
 public:
  // rotation: columns = the Gaussian's axes (scales[0] along column 0, ...).
  void add(const Eigen::Vector3d& mean, const Eigen::Matrix3d& rotation, const Eigen::Vector3d& scales, double opacity,
           const Rgb& rgb);
  // Appends a set with RGB colours (sh_degree -1), opacities clamped to kMaxOpacity.
  void append(const GaussianSet& set);
  size_t size() const { return opacities_.size(); }
  // float32 CPU tensors, RGB colours.
  GaussianSet build() const;

 private:
  std::vector<float> means_, quats_, scales_, opacities_, colors_;
};

// A footprint on the floor (rotated rectangle) that darkens the floor around it.
struct Contact {
  Eigen::Vector2d centre;  // (x, z)
  Eigen::Vector2d half;    // half sizes along the rotated axes
  double yaw = 0;          // rotation about +y, radians
  double strength = 0.45;
};

// Baked shading: ambient + a directional key light + a ceiling lamp's falloff, darkened in
// the room's corners (ambient occlusion stand-in) and around furniture contacts on the floor.
struct Lighting {
  Eigen::Vector3d key_direction{0.3, 0.8, 0.5};  // towards the light, unit
  double ambient = 0.6;
  double key = 0.4;
  Eigen::Vector3d lamp{0, 2.6, 0};
  double lamp_gain = 0.25;
  double lamp_radius = 2.5;
  Eigen::Vector3d room_min{-3, 0, -3}, room_max{3, 2.8, 3};
  Rgb tint{1.f, 1.f, 1.f};  // colour of the light
  std::vector<Contact> contacts;

  Rgb shade(const Rgb& albedo, const Eigen::Vector3d& point, const Eigen::Vector3d& normal) const;
};

class SurfelSampler {
 public:
  SurfelSampler(GaussianBuilder& out, const Lighting& lighting, SynthRng& rng)
      : out_(out), lighting_(lighting), rng_(rng) {}

  // Rectangle with corner `origin`, unit axes u and v (normal u x v) and side lengths.
  // Texture coordinates: metres along u and v plus `uv_offset`.
  void rect(const Eigen::Vector3d& origin, const Eigen::Vector3d& u, const Eigen::Vector3d& v, double length_u,
            double length_v, const Material& material, double spacing,
            const Eigen::Vector2d& uv_offset = Eigen::Vector2d::Zero());
  // Box from its centre, half sizes (x, y, z before yaw) and rotation about +y; the bottom
  // face only when `bottom` (it is hidden when the box stands on something).
  void box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half, double yaw, const Material& material,
           double spacing, bool bottom = false);
  // Surface of revolution about the vertical axis through `base`: radius(t) at height t *
  // height, t in [0, 1]; flat caps where asked and the radius is positive.
  void lathe(const Eigen::Vector3d& base, double height, const std::function<double(double)>& radius,
             const Material& material, double spacing, bool bottom_cap, bool top_cap);
  // Ellipsoid with semi-axes `radii` along the columns of `rotation`.
  void ellipsoid(const Eigen::Vector3d& centre, const Eigen::Vector3d& radii, const Eigen::Matrix3d& rotation,
                 const Material& material, double spacing);
  // Horizontal disc facing up (or down).
  void disc(const Eigen::Vector3d& centre, double radius, bool facing_up, const Material& material, double spacing);

 private:
  // One Gaussian at p, tangent axes t1, t2 (unit), cell sizes along them.
  void emit(const Eigen::Vector3d& p, const Eigen::Vector3d& t1, const Eigen::Vector3d& normal, double size1,
            double size2, const Rgb& albedo, const Material& material);

  GaussianBuilder& out_;
  const Lighting& lighting_;
  SynthRng& rng_;
};

}  // namespace ii::synth
