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
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "camera/camera.h"
#include "edit/propagate.h"
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
  // points are missing. Measured (docs/editing.md, 2026-12-03, the surface band's roles): 0.02 /
  // 0.03 / 0.035 / 0.04 gave scene 1 0.985 / 0.929, 0.989 / 0.857, 0.989 / 0.844, 0.990 / 0.840
  // and the statue 0.936 / 0.836, 0.955 / 0.829, 0.961 / 0.829, 0.965 / 0.829 (recall / precision).
  double near_object = 0.03;
  // Pixels added around each carved mask (0.5 % of the larger side gave scene 1 1.000 / 0.727
  // against 1.000 / 0.791 without).
  int dilation = 0;
  // A point of the lifted volume is the object's when it lies this close to the marked view's
  // depth at its pixel (fractions of that depth, in front and behind: the object's own surface
  // and its hidden back); the volume's others seed nothing. Scene 1 from the true mask
  // (docs/editing.md, 2026-12-03): the whole volume's points 0.997 / 0.789; 0.1 / 0.2 0.984 /
  // 0.917, 0.1 / 0.3 0.988 / 0.901, 0.1 / 0.5 0.994 / 0.822.
  double surface_in_front = 0.1, surface_behind = 0.25;
};

// What a point says to the carving: the object is here, something else is, or nothing.
enum class PointRole : uint8_t { other, object, unsure };

// The roles of `points` (world) for a region lifted from `marked` (edit/propagate.h) with
// `depth` (the marked view's, its size; 0 = unknown): inside the lifted volume and near the
// depth at their pixel the object, elsewhere in the volume unsure, outside it other.
std::vector<PointRole> point_roles(const PropagatedMasks& lifted, const Image& depth, const Camera& marked,
                                   const std::vector<Eigen::Vector3d>& points, const CarveOptions& options = {});

struct CarvedMask {
  Image mask;                   // values 0/1, the view's size
  int object_seeds = 0;         // the object's points the view sees
  int other_seeds = 0;          // other points it sees inside its propagated mask
  bool carved = false;          // false: the propagated mask, kept (no object seed)
};

// `masks` (propagated, one per view), `photo(i)` (view i's RGB photo, at its mask's size; loaded
// as each view is carved, a few at a time) and `cameras` per view; `points` (world) with their roles.
using PhotoSource = std::function<Image(size_t)>;
std::vector<CarvedMask> carve_masks(const std::vector<Image>& masks, const PhotoSource& photo,
                                    const std::vector<Camera>& cameras, const std::vector<Eigen::Vector3d>& points,
                                    const std::vector<PointRole>& roles, const CarveOptions& options = {});

}  // namespace ii
