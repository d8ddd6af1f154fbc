#pragma once
// The reference's region on the surface around it. Where the object stood, the reference's photo
// (or its 2D fill) shows what lies behind it, but nothing measured that depth: the network's guess
// puts it a few pixels off, often far off (SPIn-NeRF scene 1: the bench's end where the box stood
// at the depth of the pavement behind it), and from elsewhere the region is a blurred smear. Each
// region pixel instead takes the depth of the measured surface around the mask where that surface
// looks like it: a mean over the ring's pixels weighted by distance and by colour, in inverse
// depth, so that the bench's grey continues the bench and the hedge's green the hedge. Where the
// measured depth is a depth map, each ring pixel continues its local plane (a table top seen
// obliquely keeps its slope); a plane sweep's depth (geometry/stereo_depth.h) holds each patch
// facing the camera, so its slopes are steps and the ring's depth is continued flat. The region's
// pixels then become flat, opaque splats on that depth (geometry/surface_splats.h) in the
// reference's colours, as the measured surface does outside the mask.
#include <cstdint>

#include <nlohmann/json.hpp>

#include "common/torch.h"
#include "gaussians/gaussians.h"
#include "geometry/measured_surface.h"

namespace ii {

struct SceneInput;

// Measured on SPIn-NeRF scene 1 with an object-free photo as the reference, the held-out rooms
// and make demo (2026-11-29, bf15c3e; docs/usage.md, "The steps after the network, measured").
struct RegionSurfaceOptions {
  double opacity = 0.95;  // the splats' least opacity; 0 = none (the network's Gaussians stay)
  // A ring pixel's weight falls off over this fraction of the height from the region pixel
  // (0.02 and 0.16 lost 0.8 and 0.1 dB on scene 1's region) ...
  double spatial = 0.08;
  // ... and over this distance between their colours (RGB in 0-1, each blurred over 5 x 5 pixels
  // so that a leaf's texture does not decide it; 0.1 and 0.2 lost 0.3 and 0.7 dB).
  double colour = 0.05;
  int gap = 3;                // the ring starts this many pixels outside the mask (its edge blends the object)
  double reach = 0.1;         // and reaches this fraction of the height beyond that
  int ring_samples = 3000;    // at most this many of its pixels weigh in (evenly spaced; 1000 lost 0.1 dB)
  // With depth maps: each ring pixel's plane (its inverse depth fitted over this fraction of the
  // height) continues into the region where it fits within `slope_fit` of the depth.
  double slope_window = 1.0 / 32;
  double slope_fit = 0.02;
  // Where the weighted mean lands between two surfaces (a flying pixel of the region's depth with
  // the measured depth around it, geometry/flying_pixels.h), the pixel goes to the far one: a splat
  // between a table's edge and the floor is a speck from elsewhere (2026-11-29: the held-out rooms
  // +0.04 / +0.44 dB masked at 128² / 256², make demo's room -0.6 masked, +0.2 whole and fewer
  // specks; scene 1's region -0.03, the statue unchanged; to the side whose colour the pixel
  // shares instead, the rooms -0.35 / -0.48).
  bool far_side = true;
};

struct RegionSurface {
  int64_t gaussians = 0;  // the region pixels put on the surface
  int64_t ring = 0;       // the ring pixels that weighed in
  bool slopes = false;    // whether the ring's planes were continued (a depth map) or held flat
  int64_t far_side = 0;   // the region pixels moved to the far side of the surfaces they fell between
  // The pixels put on the surface (flat indices of the reference's maps): refinement keeps
  // their splats as they are.
  torch::Tensor pixels;
};

// Each region pixel's plane weighted by the softmax over the ring of 2 a.b - |b|^2, a its row of
// `pixels` (n, 5) and b the ring pixel's row of `ring` (m, 5), over the ring's `planes` (m, 3):
// (n, 3). `fused`: geometry/region_weights.h's kernel where the CPU has AVX2; else, and with false,
// LibTorch's softmax and products.
torch::Tensor ring_weighted_planes(const torch::Tensor& pixels, const torch::Tensor& ring, const torch::Tensor& planes,
                                   bool fused = true);

// The depth of each `region` pixel (H, W bool) from `measured` (H, W; camera z, 0 where unknown)
// outside it, weighed by `colour` (3, H, W in 0-1); with `slopes`, each ring pixel's local plane
// continued. Returns (H, W) float32: the depth at the region's pixels, 0 elsewhere and wherever
// no ring pixel is known. `ring_used`, when given, receives the ring's size.
torch::Tensor depth_from_surroundings(const torch::Tensor& measured, const torch::Tensor& region,
                                      const torch::Tensor& colour, bool slopes, const RegionSurfaceOptions& options,
                                      int64_t* ring_used = nullptr);

// In place on `maps` (the network's output for `input`, after the measured surface): the
// reference's region (its mask grown by `mask_margin` pixels, as the measured surface leaves it)
// on the depth of the measured surface around it, as flat splats of at least options.opacity in
// the reference's colours. Nothing without a mask on the reference or without its measured depth.
RegionSurface put_region_on_surface(GaussianMaps& maps, const SceneInput& input, const MeasuredDepth& measured,
                                    int mask_margin, const RegionSurfaceOptions& options);

// Whether put_region_on_surface may change `input`'s maps at all (the options ask for it, the
// reference has a mask and a measured depth): a caller copies the maps only then.
bool region_surface_may_apply(const SceneInput& input, const MeasuredDepth& measured,
                              const RegionSurfaceOptions& options);

// Checks the options; throws Error naming the bad one.
void check_region_surface_options(const RegionSurfaceOptions& options);

// What run.json and metrics.json record of it.
nlohmann::json describe_region_surface(const RegionSurfaceOptions& options, const RegionSurface& done);

}  // namespace ii
