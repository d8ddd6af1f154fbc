#include "cli/edit_options.h"

#include "inpaint/lama_inpainter.h"

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "data/view_selection.h"
#include "geometry/settings.h"
#include "model/default_model.h"

namespace ii::cli {

void add_edit_options(CLI::App* cmd, EditArgs& args) {
  auto* view = cmd->add_option("--view", args.view,
                               "The view the region is marked (or clicked) on: masks for every other view are made "
                               "from it");
  auto* mask = cmd->add_option("--mask", args.mask, "The region on that view (white = object or edit region)")
                   ->check(CLI::ExistingFile);
  auto* click = cmd->add_option("--click", args.clicks,
                                "X,Y: a click on the object in that view (pixels of its image as stored), in place "
                                "of --mask: the object is selected in the network's reconstruction and every "
                                "view's mask carved to it; repeat to add objects or parts of another colour");
  cmd->add_option("--not-click", args.not_clicks,
                                    "X,Y: a point of that view that is not the object (with --segmenter or --box); "
                                    "repeatable");
  auto* box = cmd->add_option("--box", args.box,
                              "X0,Y0,X1,Y1: a box around the object in that view (pixels of its image as stored), in "
                              "place of --mask: without a segmenter GrabCut finds the object in it by colour (the "
                              "photo outside the box is not the object; --click points in it are, --not-click "
                              "points are not); with one, the box prompts it. Then lifted to every view and carved");
  cmd->add_option("--segmenter", args.segmenter,
                  kSegmenterHelp + ". With one, the clicked view's mask from the network (one click: the best-scored of "
                  "its three masks), then lifted to every view and carved; without it, the object is grown by "
                  "colour over the reconstruction");
  mask->needs(view);
  click->needs(view);
  click->excludes(mask);
  box->needs(view);
  box->excludes(mask);
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
  cmd->add_option("--carve", args.carve,
                  "Remove with the network's depth: carve each propagated mask to the object it holds (the "
                  "reconstruction's points inside the marked volume, then GrabCut by colour; on by default: SPIn-NeRF "
                  "scene 1 from the true mask of any of its 60 views, recall 0.989 and precision 0.886 against "
                  "about 0.58 propagated); off: the propagated masks as they are")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
}

void add_reference_options(CLI::App* cmd, EditArgs& args) {
  cmd->add_option("--reference-view", args.reference_view,
                  "The reference view when the context is chosen automatically (default: the --view of a one-mask "
                  "edit, else the view nearest the middle of the capture)");
  cmd->add_option("--inpainter,--reference-inpainter", args.inpainter, kInpainterHelp + std::string("ns"));
  cmd->add_option("--inpaint-grow", args.inpaint_grow,
                  "The region the 2D inpainter paints: the reference's mask grown by this fraction of the view's "
                  "larger side, so that the object's contact shadow and edge pixels are painted over, not continued "
                  "inward (the network's mask stays the mask); 0 = the mask as it is (default: " +
                      fmt::format("{:g}", kSelectionInpaintGrow) + " for a region selected by --click or --box, 0 for a "
                      "mask given)")
      ->check(CLI::Range(0.0, 0.2));
  add_geometry_options(cmd, args.geometry);
}

namespace {

// What --help shows a setting takes, as CLI11 names its own types.
std::string type_name(const GeometrySetting& setting) {
  if (setting.kind == "number") return "FLOAT";
  if (setting.kind == "integer") return "INT";
  if (setting.kind == "bool") return "BOOLEAN";
  std::string names;
  for (const std::string& c : setting.choices) names += (names.empty() ? "" : ",") + c;
  return "TEXT:{" + names + "}";
}

// One flag of geometry/settings.h's table, written into `geometry` as it is parsed.
void add_geometry_setting(CLI::App* cmd, GeometryOptions& geometry, const GeometrySetting& setting) {
  cmd->add_option_function<std::string>(
         "--" + setting.name, [&geometry, &setting](const std::string& text) { setting.put(geometry, text); },
         setting.help)
      ->check([&setting](const std::string& text) {
        const std::string takes = check_geometry_setting(setting, text);
        return takes.empty() ? takes : "'" + text + "': expected " + takes;
      })
      ->type_name(type_name(setting))
      ->default_str(setting.get(geometry));
}

}  // namespace

void add_align_depth_option(CLI::App* cmd, GeometryOptions& geometry) {
  for (const char* name : {"align-depth", "depth-detail"}) add_geometry_setting(cmd, geometry, geometry_setting(name));
}

void add_geometry_options(CLI::App* cmd, GeometryOptions& geometry) {
  for (const GeometrySetting& setting : geometry_settings()) add_geometry_setting(cmd, geometry, setting);
}

void apply_reference_options(const EditArgs& args, SceneInputOptions& options) {
  options.reference_view = args.reference_view;
  options.inpainter = inpainter_from_flag(args.inpainter, "ns");
  if (args.inpaint_grow >= 0) options.inpaint_grow = args.inpaint_grow;
  options.geometry = args.geometry;
  if (args.mode == "insert") options.geometry = options.geometry.for_insertion();
}

std::optional<OneMask> one_mask_request(const EditArgs& args, const Scene& scene, const std::string& precision) {
  if (args.view.empty()) return std::nullopt;
  if (args.mask.empty() && args.clicks.empty() && args.box.empty())
    fail("--view {}: give the region on it, --mask FILE, --click X,Y or --box X0,Y0,X1,Y1", args.view);
  if (!args.not_clicks.empty() && args.clicks.empty() && args.box.empty())
    fail("--not-click needs --click or --box: points that are not the object go with a prompt for it");
  OneMask request;
  request.view = args.view;
  const View& view = scene.views[static_cast<size_t>(input_view_index(scene, args.view))];
  if (!args.clicks.empty() || !args.box.empty()) {
    if (args.mode != "remove")
      fail("--{} selects an object to remove: --mode insert needs --mask", args.box.empty() ? "click" : "box");
    for (const std::string& click : args.clicks) request.clicks.push_back(parse_click(click, "--click"));
    for (const std::string& click : args.not_clicks) request.not_clicks.push_back(parse_click(click, "--not-click"));
    if (!args.box.empty()) request.box = parse_view_box(args.box, "--box");
    if (const auto path = segmenter_path(args.segmenter)) {
      spdlog::info("reading the segmenter {}", path->string());
      request.segmenter = std::make_shared<const Segmenter>(Segmenter::load(
          *path, parse_segmenter_precision(precision)));
    } else if (!request.not_clicks.empty() && !request.box) {
      fail("--not-click needs --segmenter (or INSTAINPAINT_SEGMENTER) or --box: the colour growth takes no such points");
    }
  } else {
    request.region = read_region_mask(args.mask, view);
  }
  request.propagation.mode = parse_edit_mode(args.mode);
  if (args.extent > 0) request.propagation.extent = args.extent;
  request.propagation.dilation = args.dilate;
  if (args.depth_margin >= 0) request.depth_margin = args.depth_margin;
  if (!args.depth.empty()) request.depth_file = args.depth;
  request.depth_png_scale = args.depth_scale;
  request.carve = args.carve == "on";
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
