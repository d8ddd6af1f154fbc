#pragma once
// Propagated masks made tight with a reconstruction of the scene. A propagated mask is the image
// of the marked region's whole lifted volume (edit/propagate.h): it holds the object, but also what
// stands behind it and in front of it from that view. Given the scene's 3D points (a prediction's
// Gaussians, a capture's points), those inside the lifted volume are the object's. In each view,
// the points it sees (the nearest at their pixel) become seeds: the object's where they are the
// object's, the rest's inside the mask where they are not (definite away from the object's seeds),
// and OpenCV's GrabCut decides the pixels
// between the seeds by their colour. A view in which no point of the object is seen keeps its
// propagated mask. Torch-free.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "camera/camera.h"
#include "io/image.h"

namespace ii {

struct CarveOptions {
  // A point is seen in a view when its depth is within this fraction of the nearest point's at
  // its cell of the view (`cell` pixels square).
  double seen_tolerance = 0.03;
  int cell = 3;
  int iterations = 3;  // GrabCut's
  // GrabCut works at most this many pixels on a side of the mask's box and its margin (0: at the
  // photo's size). Scene 1 (docs/editing.md): 160 px 0.997 / 0.789 in a ninth of the time of the
  // full size's 0.998 / 0.806.
  int grabcut_size = 160;
  // Within this fraction of the view's larger side of an object seed, a seen point of the rest
  // only says "probably not the object": it may be one the object hides where the object's own
  // points are missing. Measured (docs/editing.md, session 45): 0.02 against 0.01 and everywhere
  // definite (statue recall 0.956 / 0.931 / 0.927, scene 1's precision 0.791 / 0.827 / 0.804).
  double near_object = 0.02;
  // Pixels added around each carved mask (0.5 % of the larger side gave scene 1 1.000 / 0.727
  // against 1.000 / 0.791 without).
  int dilation = 0;
};

struct CarvedMask {
  Image mask;                   // values 0/1, the view's size
  int object_seeds = 0;         // the object's points the view sees
  int other_seeds = 0;          // other points it sees inside its propagated mask
  bool carved = false;          // false: the propagated mask, kept (no object seed)
};

// `masks` (propagated, one per view), `photos` (RGB, the same sizes) and `cameras` per view;
// `points` (world) with `object` (1: inside the lifted volume, edit/propagate.h's inside_lifted).
std::vector<CarvedMask> carve_masks(const std::vector<Image>& masks, const std::vector<const Image*>& photos,
                                    const std::vector<Camera>& cameras, const std::vector<Eigen::Vector3d>& points,
                                    const std::vector<uint8_t>& object, const CarveOptions& options = {});

}  // namespace ii
