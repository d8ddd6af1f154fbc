// `instainpaint fill`: remove a region from any splat scene and fill the hole it leaves.
#include <fmt/core.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <sstream>

#include "cli/commands.h"
#include "cli/edit_options.h"
#include "cli/refine_options.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "common/files.h"
#include "common/stage_times.h"
#include "inpaint/lama_inpainter.h"
#include "common/stopwatch.h"
#include "data/image_ops.h"
#include "data/inpaint2d.h"
#include "fill/fill.h"
#include "io/image.h"
#include "io/splat_file.h"

namespace ii::cli {

namespace fs = std::filesystem;

namespace {

struct FillArgs {
  std::string splats;
  std::string out;
  std::string report;
  std::string box;
  std::string selection;
  std::string view;
  std::string mask;
  std::vector<std::string> clicks;      // --click X,Y (repeatable)
  std::vector<std::string> not_clicks;  // --not-click X,Y (repeatable)
  std::string segmenter;
  std::string scene_dir;
  SceneOptions scene;
  std::string cameras;
  std::string reference;
  std::string reference_view;
  std::string up;
  std::string checkpoint;
  std::string placement = "surface";
  std::string inpainter;  // empty: $INSTAINPAINT_INPAINTER, else telea
  int views = 4;
  int height = 256;
  bool all_views = false;
  bool delete_only = false;
  RefineArgs refine;
  RuntimeOptions runtime;
};

Eigen::Vector3d parse_up(const std::string& text) {
  std::vector<double> v;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    v.push_back(std::strtod(item.c_str(), &end));
    if (item.empty() || end != item.c_str() + item.size()) fail("--up '{}': expected x,y,z", text);
  }
  if (v.size() != 3 || Eigen::Vector3d(v[0], v[1], v[2]).norm() == 0) fail("--up '{}': expected x,y,z, not all zero", text);
  return {v[0], v[1], v[2]};
}

std::vector<NamedCamera> given_cameras(const FillArgs& a) {
  std::vector<NamedCamera> cameras;
  if (!a.scene_dir.empty()) {
    const Scene scene = load_scene(a.scene_dir, a.scene);
    // Every posed view: the object-free test views too (one of them may be the reference).
    for (const std::vector<View>* views : {&scene.views, &scene.test_views})
      for (const View& v : *views) cameras.push_back({v.name, v.camera});
  }
  if (!a.cameras.empty())
    for (NamedCamera& c : read_camera_json(a.cameras)) cameras.push_back(std::move(c));
  return cameras;
}

// Rows of before / removed / after, one column per camera, for looking at.
Image comparison_sheet(const FillResult& r) {
  const Image& first = r.before.at(0);
  const int w = first.width, h = first.height, gap = 4;
  const int columns = static_cast<int>(r.before.size());
  Image sheet(columns * (w + gap) - gap, 3 * (h + gap) - gap, 3, 1.f);
  auto place = [&](const Image& image, int row, int column) {
    for (int y = 0; y < std::min(h, image.height); ++y)
      for (int x = 0; x < std::min(w, image.width); ++x)
        for (int c = 0; c < 3; ++c) sheet.at(row * (h + gap) + y, column * (w + gap) + x, c) = image.at(y, x, c);
  };
  for (int i = 0; i < columns; ++i) {
    place(r.before[static_cast<size_t>(i)], 0, i);
    place(r.deleted[static_cast<size_t>(i)], 1, i);
    place(r.after[static_cast<size_t>(i)], 2, i);
  }
  return sheet;
}

void write_report(const fs::path& dir, const FillArgs& a, FillResult& r) {
  fs::create_directories(dir);
  for (size_t i = 0; i < r.before.size(); ++i) {
    const std::string& name = r.cameras.cameras[i].name;
    write_png(dir / ("before_" + name + ".png"), r.before[i]);
    write_png(dir / ("removed_" + name + ".png"), r.deleted[i]);
    write_png(dir / ("after_" + name + ".png"), r.after[i]);
    write_png(dir / ("mask_" + name + ".png"), r.masks[i]);
  }
  write_png(dir / "reference.png", r.reference);
  // The cameras as a camera list: a second run can take them (--cameras) with a reference
  // painted by another inpainter on reference.png where mask_<reference>.png is white.
  write_camera_json(dir / "cameras.json", r.cameras.cameras);
  write_png(dir / "compare.png", comparison_sheet(r));
  nlohmann::json report = r.report();
  report["input"] = a.splats;
  report["output"] = a.out;
  report["pictures"] = {{"compare", "compare.png: rows before, region removed, filled; one column per camera"},
                        {"reference", "reference.png: the inpainted reference view the network saw"},
                        {"cameras", "cameras.json: the cameras as a camera list (--cameras)"}};
  if (report.contains("refine")) write_loss_chart(dir, report["refine"]);
  write_file_atomic(dir / "fill.json", report.dump(2) + "\n");
}

void run(const FillArgs& a) {
  splat_format_of(a.out);  // a bad output name fails before the work
  if (a.views < 1) fail("--views: at least 1, got {}", a.views);
  if (a.height < 32 || a.height % 8 != 0) fail("--height: a multiple of 8 of at least 32, got {}", a.height);
  // --box: a box in the file's frame, or with --view one on that camera's picture.
  const bool view_box = !a.view.empty() && !a.box.empty();
  const int ways = (!a.box.empty() && !view_box) + !a.selection.empty() + !a.view.empty();
  if (ways != 1)
    fail("give the region one way: --box (a box in the file's frame), --selection FILE, or --view with --mask, --click "
         "or --box X0,Y0,X1,Y1 on it");
  if (!a.view.empty() && a.mask.empty() && a.clicks.empty() && !view_box)
    fail("--view {}: give the region on it, --mask FILE, --click X,Y or --box X0,Y0,X1,Y1", a.view);
  if (view_box && !a.mask.empty()) fail("--view {}: --mask or --box, not both", a.view);
  if (a.view.empty() && (!a.mask.empty() || !a.clicks.empty()))
    fail("--{} is on a view: name it with --view", a.mask.empty() ? "click" : "mask");
  FillOptions o;
  o.scene_name = a.splats;
  o.camera_options.views = a.views;
  o.camera_options.height = a.height;
  o.camera_options.reference = a.reference_view;  // empty: the stroke's --view (fill_splats), else the best
  if (!a.up.empty()) o.camera_options.up = parse_up(a.up);
  o.placement = parse_fill_placement(a.placement);
  o.inpainter = inpainter_from_flag(a.inpainter, "ns");
  o.reference_only = !a.all_views;
  o.fill = !a.delete_only;
  if (view_box)
    o.view_box = parse_view_box(a.box, "--box");
  else if (!a.box.empty())
    o.box = parse_box(a.box);
  o.cameras = given_cameras(a);
  if (!a.reference.empty()) {
    o.reference_image = read_image_rgb(a.reference);
    if (a.reference_view.empty() && a.view.empty())
      fail("--reference needs --reference-view (or --view): the camera (from --scene or --cameras) it was painted on");
  }
  if (!a.view.empty()) {
    o.stroke_view = a.view;
    if (!a.mask.empty()) o.stroke = read_mask(a.mask);
    for (const std::string& click : a.clicks) o.clicks.push_back(parse_click(click, "--click"));
    for (const std::string& click : a.not_clicks) o.not_clicks.push_back(parse_click(click, "--not-click"));
  }
  const Runtime runtime = apply_runtime_options(a.runtime);
  if (!a.clicks.empty() || view_box)
    if (const auto path = segmenter_path(a.segmenter)) {
      spdlog::info("reading the segmenter {}", path->string());
      o.segmenter = std::make_shared<const Segmenter>(Segmenter::load(
          *path, parse_segmenter_precision(a.runtime.precision)));
    }
  spdlog::info("[1/3] reading {}", a.splats);
  Stopwatch watch;
  const SplatCloud cloud = read_splats(a.splats);
  const double read_ms = watch.lap();
  if (!a.selection.empty()) {
    o.selection = read_splats(a.selection);
    o.selection_name = a.selection;
  }
  const RefineOptions refine = refine_options(a.refine);
  if (refine_requested(refine)) o.refine = refine;
  spdlog::info("[2/3] removing and filling ({} splats, {} views at {} high)", cloud.size(), a.views, a.height);
  const Predictor predictor(a.checkpoint, runtime.device, runtime.precision);
  const double load_ms = watch.lap();
  FillResult r = fill_splats(cloud, o, predictor);
  spdlog::info("[3/3] writing {}", a.out);
  watch.lap();
  write_splats(a.out, r.splats);
  // The whole command's stages: reading the file and the model, the fill's, writing the result.
  StageTimes stages;
  stages.add("read " + fs::path(a.splats).filename().string(), read_ms);
  stages.add("load the model", load_ms);
  stages.merge(r.stages);
  stages.add("write " + fs::path(a.out).filename().string(), watch.lap());
  r.stages = stages;
  const fs::path report = a.report.empty() ? fs::path(a.out).parent_path() / (fs::path(a.out).stem().string() + "-fill")
                                           : fs::path(a.report);
  write_report(report, a, r);
  fmt::print("{}: {} splats, {} removed ({}), {} added from {} views ({}); {:.2f} s; report in {}\n", a.out,
             r.splats.size(), r.removed, r.region_how, r.added, r.cameras.cameras.size(), r.cameras.how,
             r.stages.waited_ms() / 1000, report.string());
}

}  // namespace

void add_fill_command(CLI::App& app) {
  auto a = std::make_shared<FillArgs>();
  auto* cmd = app.add_subcommand("fill", "Remove a region from a splat scene (any 3DGS tool's file) and fill the hole it "
                                         "leaves; every other splat is kept as it was");
  cmd->add_option("SPLATS", a->splats, "The scene: .ply, .compressed.ply, .spz, .sog")->required()->check(CLI::ExistingFile);
  cmd->add_option("--out", a->out, "The filled scene (the format follows the name)")->required();
  cmd->add_option("--report", a->report, "Folder for fill.json and the pictures (default: beside --out, <name>-fill)");
  auto* region = cmd->add_option_group("region", "The region to remove, one of:");
  region->add_option("--box", a->box, "cx,cy,cz,sx,sy,sz[,rx,ry,rz]: centre, size and rotation (degrees about x, y, z) in "
                                      "the splat file's own frame; with --view, X0,Y0,X1,Y1: a box around the object "
                                      "in that camera's pixels (GrabCut in the splats' render from it, or with "
                                      "--segmenter its prompt)");
  region->add_option("--selection", a->selection, "The same scene with the region already deleted (e.g. SuperSplat's "
                                                  "export): the splats it lacks")
      ->check(CLI::ExistingFile);
  region->add_option("--view", a->view, "A camera (from --scene or --cameras) that --mask is drawn on or --click is on");
  auto* mask = cmd->add_option("--mask", a->mask, "With --view: one stroke over the object (white), at that camera's size")
                   ->check(CLI::ExistingFile);
  cmd->add_option("--click", a->clicks,
                  "With --view: X,Y in that camera's pixels, a click on the object: the splat there and its "
                  "neighbours alike in colour (repeat to add); with --segmenter, the object it outlines in the "
                  "scene's render from that camera")
      ->excludes(mask);
  cmd->add_option("--not-click", a->not_clicks,
                  "With --click and --segmenter, or a box on --view: X,Y on something that is not the object");
  cmd->add_option("--segmenter", a->segmenter,
                  kSegmenterHelp + " (for --click)");
  cmd->add_option("--scene", a->scene_dir, "The capture the splats were trained from (any format we read): its cameras");
  cmd->add_option("--scene-format", a->scene.format, "auto, llff, nerfstudio or colmap")->capture_default_str();
  cmd->add_option("--images", a->scene.image_folder, "The capture's image folder (e.g. images_4)");
  cmd->add_option("--cameras", a->cameras, "A camera list (render --cameras' JSON) to look from")->check(CLI::ExistingFile);
  cmd->add_option("--up", a->up, "x,y,z: the scene's up for automatic cameras (default: guessed)");
  cmd->add_option("--reference", a->reference, "The reference view with the hole painted by any 2D inpainter (see "
                                                "docs/editing.md); default: the built-in one's")
      ->check(CLI::ExistingFile);
  cmd->add_option("--reference-view", a->reference_view, "The camera to take as the reference (default: --view's, "
                                                          "else the one that sees most of the region)");
  cmd->add_option("--inpainter", a->inpainter, kInpainterHelp + std::string("ns"));
  cmd->add_option("--views", a->views, "Views the network reads")->capture_default_str();
  cmd->add_option("--height", a->height, "Working height of the views (a multiple of 8)")->capture_default_str();
  cmd->add_option("--placement", a->placement,
                  "surface: the scene's surface around the hole continued inward, one splat per hole pixel of the "
                  "reference at its full size in the reference's colours; network: the network's Gaussians of the "
                  "hole at --height")
      ->check(CLI::IsMember({"surface", "network"}))
      ->capture_default_str();
  cmd->add_flag("--all-views", a->all_views, "--placement network: new splats from every chosen view's hole (default: "
                                             "the reference's, where the inpainted picture is)");
  cmd->add_flag("--delete-only", a->delete_only, "Remove the region and add nothing (to compare with the fill)");
  cmd->add_option("--checkpoint", a->checkpoint, "--placement network: " + kCheckpointHelp);
  add_refine_options(cmd, a->refine);
  add_runtime_options(cmd, a->runtime);
  cmd->footer(
      "Examples:\n"
      "  instainpaint fill scene.ply --box 0.1,0.4,2.0,0.6,0.8,0.6 --out filled.ply\n"
      "  instainpaint fill scene.spz --scene capture/ --view IMG_0012 --mask stroke.png --out filled.spz\n"
      "  instainpaint fill scene.spz --scene capture/ --view IMG_0012 --click 512,300 --out filled.spz\n"
      "  instainpaint fill scene.spz --scene capture/ --view IMG_0012 --box 400,180,640,420 --out filled.spz\n"
      "  instainpaint fill scene.ply --selection scene-without-chair.ply --refine fast --out filled.ply\n"
      "  instainpaint fill scene.ply --box 0,0,0,1,1,1 --scene capture/ --reference-view IMG_0003 \\\n"
      "      --reference my-inpainted-IMG_0003.png --out filled.ply");
  cmd->callback([a] { run(*a); });
}

}  // namespace ii::cli
