// `instainpaint synth`: procedural scenes with exact object-removal ground truth, written in
// the LLFF / SPIn-NeRF layout (src/synth).
#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "cli/commands.h"
#include "common/error.h"
#include "common/stopwatch.h"
#include "model/device.h"
#include "synth/synth_scene.h"
#include "synth/synth_writer.h"

namespace ii::cli {

namespace {

struct SynthArgs {
  std::string out;
  int scenes = 1;
  uint64_t seed = 0;
  int first = 0;
  int views = 24;
  int test_views = 8;
  int rings = 0;
  int width = 256, height = 256;
  std::string object = "mixed";
  std::string task = "remove";
  std::string splats = "../shared/data/splats";
  std::string degrade = "none";
  double detail = 1.0;
  int downscale = 4;
  bool save_gaussians = false;
  bool no_depth = false;
  int threads = 0;
};

void progress_line(int scene, int scenes, int done, int total, double seconds) {
  const int width = 24, filled = total > 0 ? done * width / total : width;
  std::fprintf(stderr, "\rscene %d/%d [%s%s] %d/%d views, %.1f s", scene + 1, scenes, std::string(filled, '#').c_str(),
               std::string(width - filled, ' ').c_str(), done, total, seconds);
  std::fflush(stderr);
}

void run(const SynthArgs& a) {
  if (a.out.empty()) fail("--out is required");
  if (a.scenes < 1) fail("--scenes must be at least 1 (got {})", a.scenes);
  if (a.first < 0) fail("--first must be >= 0 (got {})", a.first);
  set_cpu_threads(a.threads);

  synth::SynthOptions options;
  options.views = a.views;
  options.rings = a.rings;
  options.test_views = a.test_views;
  options.width = a.width;
  options.height = a.height;
  options.object = synth::parse_object_source(a.object);
  options.splat_dir = a.splats;
  options.detail = a.detail;
  synth::SynthWriteOptions write;
  write.task = synth::parse_synth_task(a.task == "multi" ? "remove" : a.task);
  write.degrade = synth::parse_degradation(a.degrade);
  write.downscale = a.downscale;
  write.save_gaussians = a.save_gaussians;
  write.write_depth = !a.no_depth;
  if (options.object != synth::ObjectSource::procedural && synth::list_splat_objects(options.splat_dir).empty())
    spdlog::warn("no captured splats (*.ply) in '{}': every object will be procedural", a.splats);

  const std::filesystem::path out(a.out);
  std::filesystem::create_directories(out);
  Stopwatch total;
  for (int i = a.first; i < a.first + a.scenes; ++i) {
    Stopwatch watch;
    const uint64_t seed = synth::scene_seed(a.seed, i);
    options.objects = a.task == "multi" ? 2 + static_cast<int>(seed % 2) : 1;  // two or three
    const synth::SynthScene scene = synth::generate_scene(options, seed);
    const double generate_s = watch.ms() / 1000;
    write.generator = {{"command", "synth"}, {"run_seed", a.seed},         {"scene_index", i},
                       {"views", a.views},   {"test_views", a.test_views}, {"object", a.object},
                       {"detail", a.detail}, {"degrade", a.degrade},         {"task", a.task},
                       {"objects", options.objects}};
    const int index = i - a.first;
    write.progress = [&](int done, int views) { progress_line(index, a.scenes, done, views, watch.ms() / 1000); };
    const std::filesystem::path dir = out / fmt::format("scene_{:03d}", i);
    const synth::SynthWriteSummary s = synth::write_synth_scene(scene, dir, write);
    std::fprintf(stderr, "\n");
    spdlog::info(
        "{}: {} + {} test views, {} + {} Gaussians, {}, object {:.1f}% of the pixels, {:.1f} s "
        "({:.1f} s building the scene)",
        dir.string(), s.views, s.test_views, scene.background.size(), scene.object.size(),
        options.objects > 1 ? fmt::format("{} procedural objects", options.objects)
        : scene.description["object"].value("kind", "?") == "splat"
            ? "splat " + scene.description["object"].value("file", "")
            : "procedural " + scene.description["object"].value("shape", ""),
        100 * s.object_fraction, watch.ms() / 1000, generate_s);
  }
  spdlog::info("wrote {} scene(s) to {} in {:.1f} s", a.scenes, out.string(), total.ms() / 1000);
}

}  // namespace

void add_synth_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "synth", "Generate synthetic rooms with an object and exact object-removal ground truth (LLFF/SPIn-NeRF layout)");
  auto a = std::make_shared<SynthArgs>();
  cmd->add_option("--out", a->out, "Output folder; scenes go to OUT/scene_000, scene_001, ...")->required();
  cmd->add_option("--scenes", a->scenes, "Number of scenes")->capture_default_str();
  cmd->add_option("--seed", a->seed, "Run seed; scene i uses a seed derived from (seed, i)")->capture_default_str();
  cmd->add_option("--first", a->first, "Index of the first scene (to extend a run: same seed, next indices)")
      ->capture_default_str();
  cmd->add_option("--views", a->views, "Training views per scene (the object is in them)")->capture_default_str();
  cmd->add_option("--test-views", a->test_views, "Object-free test views per scene, between the training views")
      ->capture_default_str();
  cmd->add_option("--rings", a->rings,
                  "0: cameras along a random arc or forward path; 1 or 2: cameras all around the object, evenly over "
                  "360 degrees on as many rings (two heights), test views between them: a capture seen from every side")
      ->check(CLI::Range(0, 2))
      ->capture_default_str();
  cmd->add_option("--width", a->width, "Image width in pixels")->capture_default_str();
  cmd->add_option("--height", a->height, "Image height in pixels")->capture_default_str();
  cmd->add_option("--object", a->object,
                  "Inserted object: procedural (composed primitives), splat (a real captured splat from --splats), "
                  "mixed (a splat in about a third of the scenes, when --splats has any)")
      ->check(CLI::IsMember({"procedural", "splat", "mixed"}))
      ->capture_default_str();
  cmd->add_option("--task", a->task,
                  "remove: the inputs show the object, the truth is the room without it; insert: the reverse (the "
                  "reference shows the object the other inputs lack); multi: two or three objects removed at once")
      ->check(CLI::IsMember({"remove", "insert", "multi"}))
      ->capture_default_str();
  cmd->add_option("--splats", a->splats, "Folder of captured splat objects (*.ply, 3DGS or compressed)")
      ->capture_default_str();
  cmd->add_option("--degrade", a->degrade,
                  "Degradation of reference.png inside the mask, imitating 2D inpainters: none, blur, color, noise, "
                  "telea (OpenCV fill of the image with the object), mixed (one per scene)")
      ->check(CLI::IsMember({"none", "blur", "color", "noise", "telea", "mixed"}))
      ->capture_default_str();
  cmd->add_option("--detail", a->detail, "Gaussian density (1: about 2.5 px apart; higher is sharper and slower)")
      ->capture_default_str();
  cmd->add_option("--downscale", a->downscale, "K of the images_K folder (poses describe K x larger images)")
      ->capture_default_str();
  cmd->add_flag("--save-gaussians", a->save_gaussians, "Also write background.ply and object.ply");
  cmd->add_flag("--no-depth", a->no_depth, "Skip depth/ and depth_clean/ (float32 maps: most of a scene's size)");
  cmd->add_option("--threads", a->threads, "CPU threads for rendering (0 = all cores)")->capture_default_str();
  cmd->footer(
      "Each scene folder holds poses_bounds.npy, images_K/ (test_* object-free test views first, then view_* with\n"
      "the object), images_K/label/ and images_K/test_label/ (object masks), clean/ (every view without the\n"
      "object), depth/ and depth_clean/ (float32 .npy z-depth of images_K/ and clean/), reference.png,\n"
      "cameras.json and synth.json (seed, task, reference, context views). With --task insert the roles swap:\n"
      "the inputs lack the object, reference.png and the test views show it, original/ holds the test views\n"
      "without it.\n"
      "Examples:\n"
      "  instainpaint synth --out synth-data --scenes 4 --seed 7 --views 24 --test-views 8\n"
      "  instainpaint synth --out orbit-rooms --scenes 3 --seed 7 --rings 2 --views 36 --test-views 12");
  cmd->callback([a] { run(*a); });
}

}  // namespace ii::cli
