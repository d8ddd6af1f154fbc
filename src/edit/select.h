#pragma once
// One click selects an object: the point the click lands on (a reconstruction's Gaussians, a
// splat file's splats), grown in 3D over its neighbours while they stay alike in colour, and the
// selection drawn into any view as a mask that OpenCV's GrabCut makes tight (edit/carve.h).
// Torch-free.
//
//   const std::vector<uint8_t> object =
//       select_object(camera, "IMG_2707", points, colours, parse_click("512,300", "--click"));
//   const Image mask = selection_mask(camera, points, object, 1, 8);  // then carve_masks (edit/carve.h)
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "camera/camera.h"
#include "camera/click.h"
#include "edit/carve.h"
#include "io/image.h"

namespace ii {

// Points to select among and their RGB colours (a reconstruction's Gaussians' centres, a splat
// file's splats), one colour per point.
struct ColouredPoints {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3f> colours;
};

struct SelectOptions {
  // Points this close to the click (fraction of the view's larger side) can be the clicked one;
  // of those the nearest to the camera is.
  double pick_radius = 0.01;
  // Two points are neighbours within this many pixels of the clicked view at the clicked depth,
  // or within `link_spacing` times the points' typical spacing there when that is farther (a
  // splat file's splats, a coarse reconstruction, seen by a camera of many pixels).
  double link_pixels = 4, link_spacing = 2.5;
  // A neighbour joins when its colour differs by at most `colour_step` from the point it is
  // reached from and by at most `colour_spread` from the colour around the click. Colours are
  // compared as chromaticity (r, g over r + g + b) and brightness (mean of r, g, b) times
  // `brightness_weight`. Measured in docs/editing.md ("One click"): step 0.02 / spread 0.04 against
  // 0.04 / 0.07 (scene 1's precision 0.955 against 0.642, the statue's recall 0.656 against 0.793);
  // spread 0.05 against 0.04 (2026-12-03): scene 1's box whole at every height and click tried
  // (recall 0.988-0.995 against 0.533-0.994: its shaded sides lie about 0.04 from its top).
  double colour_step = 0.02, colour_spread = 0.05, brightness_weight = 0.2;
  // A click on a point farther than this fraction of the view's far depth (its 99th percentile
  // of the points it sees, or the scene's own far bound when that is farther) is on the sky or
  // the far background: an error.
  double far_background = 0.8;
  // The scene's far depth bound, when its format stores one (LLFF's poses_bounds, COLMAP's
  // points): a network's reconstruction often ends just behind the object (SPIn-NeRF scene 1: the
  // box at 70, the points' far depth 81-89, the capture's bound 268), which put clicks squarely on
  // the box beyond 0.8 of it.
  std::optional<double> scene_far;
  // Each view's mask before carving: the selection's image and this fraction of the view's
  // larger side around it (room for GrabCut to find the outline).
  double mask_margin = 0.02;
  // A selection that holds more than this share of the points the clicked view sees is the
  // ground, a wall or the sky: an error.
  double max_share = 0.5;
  // A clicked point that grows to fewer than `min_points`, or than half the points under the
  // click (an object covers its pick disc), is a stray or a fragment (SPIn-NeRF scene 1, view
  // 104503: 2 points, then 72 of its box's thousands): points at other depths under the click are
  // tried (clicked_points), up to `seed_tries` of them; the first big enough, else the largest, is kept.
  size_t min_points = 20, seed_tries = 8;
};

// An Error naming the click when it is outside `camera`'s image (checked before any work).
void check_click_inside(const Camera& camera, const std::string& view, const Click& click);
// The same for every click on the object and every point that is not it.
void check_clicks_inside(const Camera& camera, const std::string& view, const std::vector<Click>& clicks,
                         const std::vector<Click>& not_clicks = {});

// The points the click lands on in `camera`'s view (named `view` in errors): the one on the
// surface seen there (the front quarter of the depths under the click) first, then points at
// other quantiles of those depths (the middle, then around it).
// Errors name the click: outside the image, on no point, or on the far background.
// `under_count` (optional) gets how many points fall within the pick radius of the click.
std::vector<size_t> clicked_points(const Camera& camera, const std::string& view,
                                   const std::vector<Eigen::Vector3d>& points, const Click& click,
                                   const SelectOptions& options = {}, size_t* under_count = nullptr);
// The first of them.
size_t clicked_point(const Camera& camera, const std::string& view, const std::vector<Eigen::Vector3d>& points,
                     const Click& click, const SelectOptions& options = {});

// The points connected to `seed` (1) through neighbours alike in colour; `colours` RGB per point.
// Points at depth edges should be left out: they float between an object and what is behind it.
std::vector<uint8_t> grow_selection(const std::vector<Eigen::Vector3d>& points,
                                    const std::vector<Eigen::Vector3f>& colours, size_t seed, const Camera& camera,
                                    const SelectOptions& options = {});

// clicked_point, grow_selection from it, and the check that the selection is not most of the view.
std::vector<uint8_t> select_object(const Camera& camera, const std::string& view,
                                   const std::vector<Eigen::Vector3d>& points,
                                   const std::vector<Eigen::Vector3f>& colours, const Click& click,
                                   const SelectOptions& options = {});

// select_object for each click: the union of their selections (1 = selected).
std::vector<uint8_t> select_objects(const Camera& camera, const std::string& view,
                                    const std::vector<Eigen::Vector3d>& points,
                                    const std::vector<Eigen::Vector3f>& colours, const std::vector<Click>& clicks,
                                    const SelectOptions& options = {});

// Where the selected points fall in `camera`'s view: each a disc of `radius` pixels, gaps closed,
// holes filled, then `dilation` pixels added around (values 0/1, the camera's size).
Image selection_mask(const Camera& camera, const std::vector<Eigen::Vector3d>& points,
                     const std::vector<uint8_t>& selected, int radius, int dilation);

// Each camera's mask of the selection: the selected points' image (discs of 0.3 % of the side,
// options.mask_margin added around) carved by the view's photo to the selected points, every
// other point the view sees being the rest's (edit/carve.h). One per camera, run side by side.
std::vector<CarvedMask> selection_masks(const std::vector<Camera>& cameras, const PhotoSource& photo,
                                        const std::vector<Eigen::Vector3d>& points,
                                        const std::vector<uint8_t>& selected, const SelectOptions& options = {},
                                        const CarveOptions& carving = {});

}  // namespace ii
