#pragma once
// Masks for every view from one: the region a user marked on one view is lifted into 3D with
// a depth map of that view and projected into every other camera.
//
// Remove: the object's visible surface (the depth inside the region) through to the
// background behind it (the depth on a ring around the region; no deeper than the object can
// be for its size), along each region pixel's ray. Insert: from the background surface inside the region towards the camera by an
// extent (default: the region's width in 3D at that depth). Each ray segment is projected
// and drawn into every view, then holes are filled and the mask is dilated. Disjoint
// regions (connected components) are lifted one by one. Torch-free.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "camera/camera.h"
#include "io/image.h"

namespace ii {

enum class EditMode { Remove, Insert };
std::string edit_mode_name(EditMode mode);        // "remove", "insert"
EditMode parse_edit_mode(const std::string& name);  // the names above; anything else is an error

struct PropagationOptions {
  EditMode mode = EditMode::Remove;
  // Insert: how far the new object reaches towards the camera from the background, in scene
  // units; unset = the region's width in 3D.
  std::optional<double> extent;
  double depth_margin = 0.05;  // relative slack on every depth bound (conservative masks)
  // Pixels added around each propagated mask; -1 = 1 % of that view's larger side (at least 2).
  int dilation = -1;
  // Each segment starts at its own pixel's depth (dense depth that can be trusted pixel by
  // pixel); false: every segment of a region spans the region's whole depth range.
  bool pixel_depth = true;
  // Remove: an object is taken to be at most this many times as deep as it is wide (its
  // region's width in 3D), so a background far behind it does not smear the masks; 0 = reach
  // the background.
  double max_depth_ratio = 1.5;
};

// What one connected region was lifted to (reported in masks.json / run.json).
struct LiftedRegion {
  int pixels = 0;                       // region pixels in the marked view
  int depth_inside = 0, depth_ring = 0;  // pixels of known depth inside it and on its ring
  double near = 0, far = 0;             // z-depth range of its ray segments (scene units)
};

struct PropagatedMasks {
  std::vector<Image> masks;  // one per target camera, at its size, values 0/1
  std::vector<LiftedRegion> regions;
  // The lifted volume: each marked pixel's ray segment, from `near` to `far` (camera z, scene
  // units) at the marked view's size; 0 off the region.
  Image near, far;
};

// Whether each point (world) lies in the lifted volume of `lifted` (marked from `camera`).
std::vector<uint8_t> inside_lifted(const PropagatedMasks& lifted, const Camera& camera,
                                   const std::vector<Eigen::Vector3d>& points);

// `region` (1 channel, > 0.5 = marked) and `depth` (1 channel z-depth in scene units; 0,
// negative or non-finite = unknown) are at `camera`'s size. Errors: sizes that differ, an
// empty region, a region or ring without any known depth.
PropagatedMasks propagate_mask(const Image& region, const Image& depth, const Camera& camera,
                               const std::vector<Camera>& targets, const PropagationOptions& options = {});

// How well a propagated mask covers a true one: recall = true pixels covered, precision =
// propagated pixels that are true. An empty true mask has recall 1; an empty propagated
// mask has precision 1.
struct MaskAgreement {
  double recall = 1, precision = 1;
};
MaskAgreement mask_agreement(const Image& propagated, const Image& truth);

}  // namespace ii
