#include "cli/edit_options.h"

#include <spdlog/spdlog.h>

#include "data/view_selection.h"
#include "model/default_model.h"

namespace ii::cli {

void add_edit_options(CLI::App* cmd, EditArgs& args) {
  auto* view = cmd->add_option("--view", args.view,
                               "The view the region is marked on: masks for every other view are made from it");
  auto* mask = cmd->add_option("--mask", args.mask, "The region on that view (white = object or edit region)")
                   ->check(CLI::ExistingFile);
  view->needs(mask);
  mask->needs(view);
  cmd->add_option("--mode", args.mode,
                  "remove: the region shows an object to take out; insert: the edited reference shows a new "
                  "object there")
      ->check(CLI::IsMember({"remove", "insert"}))
      ->capture_default_str();
  cmd->add_option("--depth", args.depth,
                  "Depth of the marked view: .npy (H, W) z-depth in scene units or a 16-bit PNG (default: the "
                  "scene's COLMAP points, else the network's reconstruction)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--depth-scale", args.depth_scale, "Scene units per level of a 16-bit depth PNG")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--extent", args.extent,
                  "Insert: how far the new object reaches towards the camera, in scene units (default: the "
                  "region's width in 3D)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--depth-margin", args.depth_margin,
                  "How far the depth may be off, relative (default: 0.05 for --depth, 0.1 for COLMAP points, 0.3 for "
                  "the network's depth)")
      ->check(CLI::Range(0.0, 0.9));
  cmd->add_option("--dilate", args.dilate,
                  "Pixels added around every propagated mask (default: 1 % of the view's larger side, at least 2)")
      ->check(CLI::Range(0, 64));
}

void add_reference_options(CLI::App* cmd, EditArgs& args) {
  cmd->add_option("--reference-view", args.reference_view,
                  "The reference view when the context is chosen automatically (default: the --view of a one-mask "
                  "edit, else the view nearest the middle of the capture)");
  cmd->add_option("--reference-inpainter", args.inpainter,
                  "Classical 2D inpainting of the reference when no --reference is given: telea, ns "
                  "(Navier-Stokes) or patch (patches of the photo copied inward)")
      ->check(CLI::IsMember({"telea", "ns", "patch"}))
      ->capture_default_str();
  add_geometry_options(cmd, args.geometry);
}

void add_align_depth_option(CLI::App* cmd, GeometryOptions& geometry) {
  cmd->add_option_function<std::string>(
         "--align-depth", [&geometry](const std::string& name) { geometry.align_depth = parse_depth_points(name); },
         "Scale each context view's predicted depth to the scene's own 3D points: depth-maps (a synthetic "
         "scene's depth/), photos (those, else points triangulated from the context views' photos and "
         "their neighbours with the scene's cameras), any (depth maps, else COLMAP's sparse points, else "
         "the photos'), none (the network's depth as it is, the paper's). One-mask propagation reads photos as "
         "depth-maps (the statue's masks lost precision with the photos' points)")
      ->check(CLI::IsMember({"none", "depth-maps", "photos", "any"}))
      ->default_str(depth_points_name(geometry.align_depth));
  cmd->add_option("--depth-detail", geometry.depth_detail.detail,
                  "With --align-depth: how closely each view's depth follows the points beyond one scale per view, "
                  "as the width of its local correction in point spacings (the network often draws a table at the "
                  "floor's depth); 0 = one scale per view")
      ->check(CLI::Range(0.0, 64.0))
      ->capture_default_str();
}

void add_geometry_options(CLI::App* cmd, GeometryOptions& geometry) {
  add_align_depth_option(cmd, geometry);
  cmd->add_option("--measured-surface", geometry.measured_surface.opacity,
                  "Where a context view has its own depth map (<scene>/depth/<view>.npy: a depth camera's, a "
                  "synthetic scene's) or, without one, a depth its context photos measure (--stereo-depth), put its "
                  "Gaussians outside its mask on that depth as flat splats along the measured surface, at least this "
                  "opaque, and inside its mask what lies outside the reference's "
                  "mask from the reference's camera (the scene beside the object); 0 = none (the network's "
                  "Gaussians, aligned as --align-depth says; --align-depth none turns this off too)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option_function<std::string>(
         "--flying-pixels",
         [&geometry](const std::string& where) {
           geometry.measured_surface.far_side = geometry.region_surface.far_side = where == "far";
         },
         "A depth map's pixels that straddle an edge (a depth between the near and the far side, as depth "
         "cameras and supersampled synthetic depth give), and the reference's region pixels whose depth from "
         "the surface around them falls between two surfaces: far = moved to the far side (a depth map's in "
         "its colour), so that they do not float as specks between the two; keep = where they were measured")
      ->check(CLI::IsMember({"far", "keep"}))
      ->default_str(geometry.measured_surface.far_side ? "far" : "keep");
  cmd->add_option("--stereo-depth", geometry.measured_surface.from_photos,
                  "Where no context view has a depth map, measure each one's depth from the context photos "
                  "themselves (a plane sweep between them about the network's aligned depth) and use it as the "
                  "measured surface where the photos are textured and agree (false: the network's Gaussians there)")
      ->capture_default_str();
  cmd->add_option("--stereo-planes", geometry.measured_surface.stereo.planes,
                  "Depths the stereo sweep tries per pixel")
      ->check(CLI::Range(3, 1024))
      ->capture_default_str();
  cmd->add_option("--stereo-spread", geometry.measured_surface.stereo.spread,
                  "The stereo sweep tries depths from the network's / N to its x N")
      ->check(CLI::Range(1.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--stereo-rows", geometry.measured_surface.stereo.rows,
                  "The stereo sweep matches the pictures at about this many rows")
      ->check(CLI::Range(16, 4096))
      ->capture_default_str();
  cmd->add_option("--stereo-min-ncc", geometry.measured_surface.stereo.min_ncc,
                  "A stereo depth whose best match correlates less (normalised cross-correlation) is unknown")
      ->check(CLI::Range(-1.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--stereo-consistency", geometry.measured_surface.stereo.consistency,
                  "Another view's stereo depth must agree within this relative difference")
      ->check(CLI::Range(0.0, 10.0))
      ->capture_default_str();
  cmd->add_option("--fade-floaters", geometry.floaters.fade,
                  "Gaussians on a depth edge of their view (a blend of the near and the far surface) that lie in "
                  "front of another context view's depth there keep this fraction of their opacity, so that they "
                  "do not smear across other views; 1 = none faded (the paper's)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--frame-margin", geometry.frame_margin.fraction,
                  "Continue each context view's Gaussians past the edges of its picture by this fraction of its "
                  "height (its border pixels repeated outward along their rays), so that views a little beside the "
                  "context cameras show the scene's edge instead of the background; 0 = none (the paper's)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--frame-margin-outer", geometry.frame_margin.outer_fraction,
                  "Past --frame-margin, continue the margin out to this fraction of the height more sparsely: one "
                  "Gaussian per --frame-margin-stride pixels square, as wide as that square (no more than "
                  "--frame-margin: none)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--frame-margin-stride", geometry.frame_margin.outer_stride,
                  "The outer frame margin's pixels per Gaussian along each side")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  cmd->add_option("--frame-margin-drop-seen", geometry.frame_margin.drop_seen_through,
                  "Drop the frame margin's Gaussians that another context view sees through (they lie in front of "
                  "the depth it saw there), so that a repeated border does not stand in front of what the other "
                  "views saw (false: keep the whole margin)")
      ->capture_default_str();
  cmd->add_option("--behind-edges", geometry.behind_edges.fraction,
                  "Continue the far side of each context view's depth edges under the near side by this fraction "
                  "of its height (those another context view sees through dropped), so that a camera beside it "
                  "sees the ground behind an object's edge instead of the background; twice as far where the depth "
                  "is the views' depth maps; 0 = none (the paper's)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--behind-edges-jump", geometry.behind_edges.jump,
                  "A depth edge for --behind-edges: the far side more than this fraction farther than its neighbour")
      ->check(CLI::Range(0.001, 10.0))
      ->capture_default_str();
  cmd->add_option("--region-surface", geometry.region_surface.opacity,
                  "With --measured-surface: put the reference's region on the measured depth around it (each pixel "
                  "on the surrounding surface its colour resembles: the hedge's green on the hedge, the bench's "
                  "grey on the bench) as flat splats at least this opaque, in the reference's colours; 0 = none "
                  "(the network's depth there); off for --mode insert")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--region-surface-colour", geometry.region_surface.colour,
                  "With --region-surface: how far (RGB distance, 0-1) a surrounding pixel's colour may be from a "
                  "region pixel's and still lend it its depth")
      ->check(CLI::Range(0.001, 2.0))
      ->capture_default_str();
  cmd->add_option("--region-cover", geometry.region_cover.opacity,
                  "Cover the reference's region with flat splats of this opacity on its depth, beside the network's "
                  "Gaussians, so that views from elsewhere show no background between them where the object "
                  "stood; 0 = none (the paper's)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
}

void apply_reference_options(const EditArgs& args, SceneInputOptions& options) {
  options.reference_view = args.reference_view;
  options.inpainter = parse_inpainter(args.inpainter);
  options.geometry = args.geometry;
  if (args.mode == "insert") options.geometry = options.geometry.for_insertion();
}

std::optional<OneMask> one_mask_request(const EditArgs& args, const Scene& scene) {
  if (args.view.empty()) return std::nullopt;
  OneMask request;
  request.view = args.view;
  request.region = read_region_mask(args.mask, scene.views[static_cast<size_t>(input_view_index(scene, args.view))]);
  request.propagation.mode = parse_edit_mode(args.mode);
  if (args.extent > 0) request.propagation.extent = args.extent;
  request.propagation.dilation = args.dilate;
  if (args.depth_margin >= 0) request.depth_margin = args.depth_margin;
  if (!args.depth.empty()) request.depth_file = args.depth;
  request.depth_png_scale = args.depth_scale;
  return request;
}

const Predictor& LazyPredictor::get() {
  if (!predictor_) {
    const Runtime runtime = apply_runtime_options(runtime_);
    spdlog::info("loading model {} for the marked view's depth", checkpoint_.empty() ? kDefaultModelName : checkpoint_);
    predictor_.emplace(checkpoint_, runtime.device, runtime.precision);
  }
  return *predictor_;
}

}  // namespace ii::cli
