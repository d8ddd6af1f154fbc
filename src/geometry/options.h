#pragma once
// What happens to the network's output before it becomes Gaussians: the geometry's steps and
// their options (each step's own header says what it does). Predictor::predict runs them in
// order after the network (predict/predictor.h); every step is recorded under "geometry" in
// run.json and metrics.json.
#include <string>

#include "geometry/behind_edges.h"
#include "geometry/floaters.h"
#include "geometry/frame_margin.h"
#include "geometry/measured_surface.h"
#include "geometry/region_cover.h"
#include "geometry/region_surface.h"

namespace ii {

// Which of a scene's own 3D points the network's depth is aligned to. COLMAP's sparse points are
// not the default: on the fern they scaled the views' depth by 0.90-0.97 and its held-out views
// lost 0.4 dB (16.88 -> 16.50; the weights of 2026-11-26: 0.6), where the points triangulated from the
// context views' photos (0.97-1.02) gained 0.1 and the synthetic rooms' depth maps gained too
// (see the model card).
enum class DepthPoints { none, depth_maps, photos, any };
const char* depth_points_name(DepthPoints points);  // "none", "depth-maps", "photos", "any"
DepthPoints parse_depth_points(const std::string& name);  // an Error naming the choices

// Predictor::predict, with align_depth: how closely each view's depth follows the scene's points
// beyond one scale per view (geometry/depth_alignment.h).
struct DepthDetailOptions {
  // The correction's width in point spacings (the mean distance between the points the view sees
  // outside its mask; 0 = one scale per view).
  double detail = 1.5;
  double prior = 0.3;      // the points' weight that pulls the correction back to the view's scale
  double max_ratio = 3.0;  // the most one point corrects, either way
  double front = 1.2;      // a point this much farther than the nearest beside it counts as hidden
  // Inside a view's mask the correction is this many times wider: the hole's depth follows its
  // wider surroundings rather than the edge of the object that stood there (held-out rooms at
  // 256², 2 spacings: 23.92 dB masked with the same width, 25.46 with 3x; 2026-11-28, ec2bb79;
  // docs/usage.md, "The steps after the network, measured").
  double region_factor = 4;
};

// What Predictor::predict does with the network's output before it makes Gaussians of it: each
// step is recorded under "geometry" in run.json and metrics.json. One struct, so that the
// commands, the server and the Python layer carry the steps whole; what a user sets of it is
// geometry/settings.h's table (the flags, Python's keywords, the paper's preset, the insert rule).
struct GeometryOptions {
  // Each context view's depth scaled to the scene's own 3D points (geometry/depth_alignment.h):
  // those of its depth maps (synthetic scenes), else points triangulated from the context views'
  // photos (the default: on real captures the default model's depth is 1.3-5x too near), or
  // with `any` its COLMAP points before the photos', or none (the network's output as it is,
  // the paper's).
  DepthPoints align_depth = DepthPoints::photos;
  DepthDetailOptions depth_detail;
  // With align_depth other than none: where a context view has its own depth map (a depth
  // camera's, a synthetic scene's), its Gaussians outside its mask lie on that surface as flat,
  // opaque splats (geometry/measured_surface.h); opacity 0 = none.
  MeasuredSurfaceOptions measured_surface;
  // With a measured surface: the reference's region on the measured depth around it, chosen by
  // colour, as opaque flat splats (geometry/region_surface.h); opacity 0 = none. Off for an
  // insertion, whose region holds a new object rather than what lies behind.
  RegionSurfaceOptions region_surface;
  // Gaussians on a view's depth edges that another view sees through keep a fraction of their
  // opacity (geometry/floaters.h); fade 1 = none (the paper's).
  FloaterOptions floaters;
  // Each view's Gaussians continued past the edges of its picture (geometry/frame_margin.h);
  // fraction 0 = none (the paper's).
  FrameMarginOptions frame_margin;
  // The far side of each view's depth edges continued under the near side
  // (geometry/behind_edges.h); fraction 0 = none (the paper's).
  BehindEdgesOptions behind_edges;
  // The reference's region covered by flat splats besides the network's Gaussians
  // (geometry/region_cover.h); opacity 0 = none (the paper's).
  RegionCoverOptions region_cover;

  // Every step off: the network's Gaussians as the paper's code makes them (each switch of
  // geometry/settings.h's table at its `off` value).
  static GeometryOptions papers();
  // For an insertion: the region holds a new object, not the surface around it, so the steps the
  // table marks (the region surface) are off: the one rule for the commands, eval and the server.
  GeometryOptions for_insertion() const;
};

}  // namespace ii
