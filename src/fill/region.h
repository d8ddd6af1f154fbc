#pragma once
// The region of a splat scene to remove, chosen one of three ways: a box in the scene's own
// frame, the Gaussians another file lacks (the same scene with the object deleted in another
// tool), one stroke or clicks on one camera's view.
#include <Eigen/Dense>

#include <filesystem>
#include <string>
#include <vector>

#include "camera/box.h"
#include "camera/camera.h"
#include "edit/select.h"
#include "io/image.h"
#include "io/ply.h"
#include "segment/segmenter.h"

namespace ii {

// One flag per splat of `cloud`: true = in the region.
using RegionMask = std::vector<bool>;

// The splats whose centres lie in the box.
RegionMask region_in_box(const SplatCloud& cloud, const OrientedBox& box);

// The splats of `cloud` that `kept` lacks: matched by their positions' exact bits, or, when
// fewer than half of kept's splats match that way (a file re-quantised by a compressed format),
// by the nearest position within a thousandth of the scene's extent. `kept_name` names kept in
// errors (a file that is not the same scene).
RegionMask region_missing_from(const SplatCloud& cloud, const SplatCloud& kept, const std::string& kept_name);

// The Gaussians that make the visible surface under `stroke` (> 0.5, at the camera's image
// size) seen from `camera`, grown in 3D as one-mask editing grows a region: the splats whose
// centres project into the stroke, from the nearest of the surface the camera sees there to as
// far behind it as the marked surface is wide.
RegionMask region_under_stroke(const SplatCloud& cloud, const Camera& camera, const Image& stroke);

// The objects under `clicks` on `camera`'s view (named `view` in errors): grown over the opaque
// splats alike in colour; where that gives a speck (a trained file), selected in the splats' render
// from that camera (about 256 rows) as in a photo: its per-pixel points at the render's depth
// grown from the click over neighbours alike in colour (edit/select.h), the outline carved by the
// render, lifted to the splats as a stroke (region_under_stroke), and the rest of the object that
// colour belongs to added (fill/whole_object.h).
RegionMask region_from_clicks(const SplatCloud& cloud, const Camera& camera, const std::string& view,
                              const std::vector<Click>& clicks, const SelectOptions& options = {});

// What `camera` sees of the splats (their render, RGB): what a segmenter is shown.
Image splats_seen(const SplatCloud& cloud, const Camera& camera);

// The object `segmenter` outlines under `clicks` (and not at `not_clicks`) in the scene's render
// from `camera` (what a user sees there), taken as a stroke; `clicked` (optional) gets the
// segmenter's mask and scores.
RegionMask region_from_segmented_clicks(const SplatCloud& cloud, const Camera& camera, const std::string& view,
                                        const std::vector<Click>& clicks, const std::vector<Click>& not_clicks,
                                        const Segmenter& segmenter, ClickedMask* clicked = nullptr);

// The object in `box` on `camera`'s view of the splats (their render, what a user sees there):
// with `segmenter` its outline for the box (and the clicks), else GrabCut's in the render (clicks
// in the box the object, `not_clicks` not), taken as a stroke; `clicked` (optional, with a
// segmenter) gets its mask and scores.
RegionMask region_from_view_box(const SplatCloud& cloud, const Camera& camera, const std::string& view,
                                const ViewBox& box, const std::vector<Click>& clicks,
                                const std::vector<Click>& not_clicks, const Segmenter* segmenter,
                                ClickedMask* clicked = nullptr);

int64_t region_count(const RegionMask& region);

// The box that holds the middle 98 % of the splats' centres along each axis (for messages and
// for framing): min and max corners.
std::pair<Eigen::Vector3d, Eigen::Vector3d> splat_bounds(const SplatCloud& cloud, const RegionMask* only = nullptr);

// Every value a renderer reads is finite: an Error naming `name`, the first bad splat and what
// is wrong otherwise.
void check_splats_finite(const SplatCloud& cloud, const std::string& name);

}  // namespace ii
