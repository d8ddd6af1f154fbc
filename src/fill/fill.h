#pragma once
// Fill the hole: remove a region from any splat scene and fill what it hid. The rest of the
// scene is rendered from cameras that see the region, each view's mask is where the region
// was visible, the reference view's hole is painted by a 2D inpainter (the built-in one, or the
// caller's image), and new splats for the hole are added in the scene's frame and scale: on the
// scene's surface around the hole continued inward (the default), or the network's Gaussians of
// the masked pixels. Every other splat is kept as it was, bit for bit.
#include <nlohmann/json.hpp>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/stage_times.h"
#include "fill/cameras.h"
#include "fill/region.h"
#include "io/image.h"
#include "predict/predictor.h"
#include "refine/refine.h"

namespace ii {

// Where the new splats come from. surface: the kept scene's depth around the hole continued
// inward, one flat splat per hole pixel of the reference view at its full size in the
// reference's colours, then whatever another chosen view still sees uncovered of its hole
// likewise; network: the network's Gaussians of the reference's hole pixels at the working
// size, their depth scaled to the scene's around the hole.
enum class FillPlacement { surface, network };
const char* fill_placement_name(FillPlacement placement);
FillPlacement parse_fill_placement(const std::string& name);  // an Error naming the choices

struct FillOptions {
  // The region, exactly one of: a box; the same scene with the region deleted (`selection`,
  // named `selection_name`); a stroke (at that camera's size) or clicks on the given camera
  // `stroke_view`.
  std::optional<OrientedBox> box;
  std::optional<SplatCloud> selection;
  std::string selection_name;
  std::string stroke_view;
  std::optional<Image> stroke;
  std::vector<Click> clicks;
  // With a segmenter, the clicks (and `not_clicks`, points that are not the object) prompt it on
  // the scene's render from that camera; its outline is taken as a stroke. Without, the splat
  // under each click is grown by colour (fill/region.h).
  std::vector<Click> not_clicks;
  // A box around the object on that camera's view (with or without `clicks` inside it): with a
  // segmenter its prompt; without, GrabCut in the scene's render from that camera
  // (edit/box_select.h). The outline is taken as a stroke.
  std::optional<ViewBox> view_box;
  std::shared_ptr<const Segmenter> segmenter;
  // Cameras to look from (a capture's, a camera list); empty: automatic ones around the region.
  std::vector<NamedCamera> cameras;
  FillCameraOptions camera_options;
  // The reference view's 2D-inpainted image (at the reference camera's size or the working
  // size); none: the built-in inpainter's.
  std::optional<Image> reference_image;
  Inpainter inpainter;
  FillPlacement placement = FillPlacement::surface;
  // The network's placement: which views' hole pixels become Gaussians: the reference's alone (true), or every chosen
  // view's. The reference's hole holds the inpainted picture, the others' nothing: a model that
  // adds its input's colour (the built-in one) gives them a grey guess. Synthetic rooms: equal or
  // better in every room (26.2 dB against 24.9 in one); the statue: grass and bush, not grey.
  bool reference_only = true;
  // false: the region removed and nothing added (deletion alone, to compare with).
  bool fill = true;
  // Optimise the new Gaussians alone against the views (the rest of the scene fixed).
  std::optional<RefineOptions> refine;
  std::string scene_name = "splats";  // names the input in messages
};

struct FillResult {
  SplatCloud splats;                   // kept splats as they were, then the new ones
  int64_t total = 0, removed = 0, added = 0;
  int64_t dropped = 0;  // the network's splats of hole pixels left out: they would hide what another view saw
  ChosenCameras cameras;               // at the working size, the reference first
  std::vector<Image> before, deleted, after, masks;  // per camera: renders, and where the region was
  Image reference;                     // the inpainted reference the network saw
  std::vector<double> depth_scales;    // per camera: the network's depth scaled to the scene's around the hole
  FillPlacement placement = FillPlacement::surface;
  // What painted the reference's hole: "given" (the caller's picture), else the built-in inpainter's name.
  std::string inpainter = "given";
  nlohmann::json inpainter_file;  // a learned inpainter's file, network and SHA-256 (null otherwise)
  // The surface placement: the reference's size it was placed at, and per chosen camera the hole
  // pixels still uncovered after the reference's splats (filled from that view).
  int surface_width = 0, surface_height = 0;
  std::vector<int64_t> uncovered;
  std::string region_how;              // how the region was chosen
  nlohmann::json segmenter;            // with a segmenter: its file, network, mask chosen and scores
  nlohmann::json refine_report;        // with refinement
  nlohmann::json model;                // Predictor::describe(): the checkpoint, and the CPU's kernels
  StageTimes stages;

  nlohmann::json report() const;  // fill.json
};

// The region `options` names: an Error when it holds no splat (giving the scene's bounds) or
// every splat.
RegionMask choose_region(const SplatCloud& cloud, const FillOptions& options);

FillResult fill_splats(const SplatCloud& cloud, const FillOptions& options, const Predictor& predictor);

}  // namespace ii
