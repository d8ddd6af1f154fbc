// `instainpaint reconstruct`: 3D Gaussian splatting of a whole posed capture (refine/reconstruct.h).
#include <fmt/core.h>
#include <spdlog/spdlog.h>

#include <filesystem>

#include "cli/commands.h"
#include "cli/refine_options.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "common/files.h"
#include "io/image.h"
#include "io/splat_file.h"
#include "refine/reconstruct.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"

namespace ii::cli {

namespace fs = std::filesystem;

namespace {

struct ReconstructArgs {
  std::string scene_dir;
  SceneOptions scene;
  std::string out = "scene.ply";
  std::string length = "balanced";
  int steps = -1;  // -1: --length
  int height = 0;
  bool eval = false;
  int64_t max_splats = 1500000;
  int sh_degree = 3;
  uint64_t seed = 0;
  std::string start, resume, write_colmap, previews, lpips_vgg;
  int checkpoint_every = 1000;
  std::vector<float> background = {1.f, 1.f, 1.f};
  bool json = false;
  RuntimeOptions runtime;
};

// OUT's checkpoint: scene.ply -> scene.checkpoint.ply and scene.checkpoint.json.
fs::path checkpoint_path(const fs::path& out, const char* extension) {
  return out.parent_path() / (out.stem().string() + ".checkpoint" + extension);
}

// Truth beside render for each scored view (at most 8), one PNG each: what the scores say, seen.
void write_previews(const fs::path& dir, const GaussianSet& g, const std::vector<View>& views, int height,
                    const std::array<float, 3>& background) {
  torch::NoGradGuard no_grad;
  RenderOptions look;
  look.background = background;
  fs::create_directories(dir);
  std::vector<View> shown;  // only those decoded
  const size_t every = std::max<size_t>(1, (views.size() + 7) / 8);
  for (size_t i = 0; i < views.size(); i += every) shown.push_back(views[i]);
  for (const PreparedView& v : working_views(shown, height)) {
    const torch::Tensor drawn = render(g, {v.camera}, look).rgb.clamp(0, 1).to(torch::kCPU, torch::kFloat32);
    const torch::Tensor truth = image_to_tensor(v.rgb)[0].permute({1, 2, 0});
    write_png(dir / (v.name + ".png"), image_from_hwc(torch::cat({truth, drawn}, 1).contiguous()));
  }
}

ReconstructOptions options_of(const ReconstructArgs& a, const Runtime& runtime) {
  ReconstructOptions o;
  o.training = reconstruct_training(a.length, a.steps);
  o.training.sh_degree = a.sh_degree;
  o.training.seed = a.seed;
  // The progress line, and once, when densification reaches the budget, that it stops growing there.
  auto line = progress_line("reconstruct");
  auto said = std::make_shared<bool>(false);
  o.training.progress = [line, said, budget = a.max_splats](const RefineProgress& p) {
    if (!*said && p.gaussians >= budget) {
      *said = true;
      spdlog::info("{} splats at step {}: --max-splats {} reached, densification adds no more", p.gaussians, p.step,
                   budget);
    }
    line(p);
  };
  o.training.background = {a.background[0], a.background[1], a.background[2]};
  o.height = a.height;
  o.eval = a.eval;
  o.max_splats = a.max_splats;
  o.device = runtime.device;
  o.lpips = lpips_scorer(a.lpips_vgg);  // before the training: a wrong file fails first
  return o;
}

// --resume: the checkpoint's Gaussians and where its run stood, refused for another scene.
void resume_from(const ReconstructArgs& a, const Scene& scene, ReconstructOptions& o) {
  const fs::path record = a.resume;
  const ReconstructCheckpoint c = parse_checkpoint(read_file_text(record), record.string());
  const std::string here = scene_fingerprint(scene.views, o.height);
  if (c.fingerprint != here)
    fail("--resume {}: the checkpoint is of other views (another scene, --height, --eval or --images): {} here, {} "
         "there",
         record.string(), here, c.fingerprint);
  const fs::path splats = record.parent_path() / (record.stem().string() + ".ply");
  o.start = gaussians_from_splats(read_splats(splats), c.sh_degree);
  o.training.steps = c.steps;
  o.training.time_budget_s = c.time_budget_s;
  o.training.first_step = c.step;
  o.training.first_fraction = c.time_budget_s > 0 ? c.fraction : 0;
  o.training.sh_degree = c.sh_degree;
  o.training.seed = c.seed;
  spdlog::info("resuming {} at step {} ({:.0f} % of the run)", splats.string(), c.step, 100 * c.fraction);
}

void run(const ReconstructArgs& a) {
  if (a.scene_dir.empty()) fail("reconstruct: give the capture's folder (SCENE or --scene)");
  const Runtime runtime = apply_runtime_options(a.runtime);
  const fs::path out = a.out;
  splat_format_of(out);  // a bad output name fails before the work
  SceneOptions scene_options = a.scene;
  if (a.eval) scene_options.hold_out_every = 8, scene_options.hold_out_whole = true;
  spdlog::info("[1/4] reading {}", a.scene_dir);
  const Scene scene = load_scene(a.scene_dir, scene_options);
  ReconstructOptions o = options_of(a, runtime);
  if (!a.resume.empty()) resume_from(a, scene, o);
  if (!a.start.empty()) o.start = gaussians_from_splats(read_splats(a.start), a.sh_degree);

  if (!a.write_colmap.empty()) {
    const std::vector<PreparedView> views = working_views(scene.views, o.height);
    const StartPoints points = start_points(scene, views);
    write_colmap_start(a.write_colmap, views, points);
    if (!o.start) o.points = points;  // the same start for both trainers, made once
    spdlog::info("wrote the {} training views and their start points as a COLMAP folder {}", views.size(),
                 a.write_colmap);
  }

  // Checkpoints beside OUT: the Gaussians as a splat file, then the record naming the step.
  const std::string fingerprint = scene_fingerprint(scene.views, o.height);
  o.training.checkpoint_every = a.checkpoint_every;
  const RefineOptions length = o.training;
  o.training.checkpoint = [&, length](int step, const GaussianSet& g) {
    // Runs of --steps alone (see --help), and none at their end: the splat file is the result.
    if (length.time_budget_s > 0 || step >= length.steps) return;
    ReconstructCheckpoint c;
    c.fingerprint = fingerprint;
    c.step = step;
    c.steps = length.steps;
    c.fraction = double(step) / length.steps;
    c.sh_degree = length.sh_degree;
    c.seed = length.seed;
    write_splats(checkpoint_path(out, ".ply"), splats_from_gaussians(g.to(torch::kCPU)));
    write_file_atomic(checkpoint_path(out, ".json"), checkpoint_json(c));
  };

  spdlog::info("[2/4] {} views at {} rows, {}{}", scene.views.size(),
               a.height > 0 ? std::to_string(a.height) : std::string("their own"), refine_length(o.training),
               a.eval ? fmt::format(", {} held out", scene.test_views.size()) : std::string());
  const ReconstructResult r = reconstruct_scene(scene, o);
  spdlog::info("[3/4] writing {} ({} splats)", out.string(), r.gaussians.size());
  if (out.has_parent_path()) fs::create_directories(out.parent_path());
  write_splats(out, splats_from_gaussians(r.gaussians.to(torch::kCPU)));
  nlohmann::json report = reconstruct_report(r, o);
  report["scene"] = a.scene_dir;
  report["out"] = out.string();
  const fs::path previews =
      a.previews.empty() ? out.parent_path() / (out.stem().string() + "-previews") : fs::path(a.previews);
  spdlog::info("[4/4] previews of the {} in {}", a.eval ? "held-out views" : "training views", previews.string());
  write_previews(previews, r.gaussians.to(torch::kCPU), a.eval ? scene.test_views : scene.views, o.height,
                 o.training.background);
  const fs::path report_path = out.parent_path() / (out.stem().string() + ".json");
  write_file_atomic(report_path, report.dump(2) + "\n");
  if (a.json) {
    fmt::print("{}\n", report.dump(2));
    return;
  }
  fmt::print("{}: {} splats from {} ({} points), {} steps in {:.0f} s; {} {}: PSNR {:.2f} dB, SSIM {:.4f}{}\n",
             out.string(), r.gaussians.size(), r.start_source, r.start_points, r.training.steps, r.train_s,
             r.scores.size(), a.eval ? "held-out views" : "training views", r.mean_psnr, r.mean_ssim,
             r.mean_lpips ? fmt::format(", LPIPS {:.4f}", *r.mean_lpips) : std::string());
}

}  // namespace

void add_reconstruct_command(CLI::App& app) {
  auto a = std::make_shared<ReconstructArgs>();
  auto* cmd = app.add_subcommand(
      "reconstruct",
      "Train 3D Gaussian splats of a whole posed capture (3DGS), e.g. an orbit around an object, to click and Fill");
  cmd->footer(R"(
Starts from the capture's COLMAP points (points3D), else from points triangulated from its photos
with its own poses. SH up to degree 3, densification and opacity resets as 3DGS does them, on the
GPU when LibTorch sees one. Writes OUT, OUT's report (.json beside it: the scores, the splat
counts, each stage's seconds) and previews (truth | render) of the scored views.

Examples:
  instainpaint reconstruct shared/data/realtrain/custom_coffee_cup --height 256 --out cup.ply
  instainpaint reconstruct CAPTURE --eval --steps 3000 --out scene.ply        # every 8th view scored
  instainpaint reconstruct CAPTURE --resume scene.checkpoint.json --out scene.ply
  instainpaint reconstruct CAPTURE --eval --start other-trainer.ply --steps 0  # score a splat file
  instainpaint fill scene.ply --scene CAPTURE --view 12 --click 400,300 --out filled.ply)");
  cmd->add_option("SCENE", a->scene_dir, "The capture's folder (as --scene)")->check(CLI::ExistingDirectory);
  add_scene_options(cmd, a->scene_dir, a->scene);
  cmd->get_option("--scene")->required(false);
  cmd->add_option("--out", a->out, "Splat file to write (.ply, .compressed.ply, .spz, .sog)")->capture_default_str();
  cmd->add_option("--length", a->length,
                  "How long: fast (1 minute), balanced (9 minutes), best (20 minutes) or a time (90s, 2m)")
      ->capture_default_str()
      ->check([](const std::string& text) {
        try {
          refine_setting(text);
          return std::string();
        } catch (const Error& e) {
          return std::string(e.what());
        }
      });
  cmd->add_option("--steps", a->steps,
                  "A number of steps instead of --length (the same run on any machine; 0: score the start alone)")
      ->check(CLI::Range(0, 10000000));
  cmd->add_option("--height", a->height, "Rows of the pictures trained on (0: the photos', at most 1600 on the long side)")
      ->capture_default_str()
      ->check(CLI::Range(0, 16384));
  cmd->add_flag("--eval", a->eval,
                "Hold out every eighth view (0, 8, 16, ...: 3DGS's and gsplat's eval) and score it (PSNR, SSIM; "
                "LPIPS with --lpips-vgg); "
                "without it every view trains and the training views are scored");
  cmd->add_option("--lpips-vgg", a->lpips_vgg,
                  "torchvision's VGG16 weights (vgg16-397923af.pth): the scores add LPIPS (VGG, as 3DGS's eval); "
                  "default $INSTAINPAINT_LPIPS_VGG")
      ->check(CLI::ExistingFile);
  cmd->add_option("--max-splats", a->max_splats,
                  "Densification adds no splat past this many (the memory a run needs grows with them)")
      ->capture_default_str()
      ->check(CLI::Range(int64_t{1000}, int64_t{100000000}));
  cmd->add_option("--sh-degree", a->sh_degree, "Spherical harmonics degree (0: one colour per splat)")
      ->capture_default_str()
      ->check(CLI::Range(0, 3));
  cmd->add_option("--seed", a->seed, "The order the views are visited in")->capture_default_str();
  cmd->add_option("--start", a->start, "Start from this splat file instead of the capture's points")
      ->check(CLI::ExistingFile);
  cmd->add_option("--checkpoint-every", a->checkpoint_every,
                  "With --steps: write OUT's checkpoint (NAME.checkpoint.ply and .json) every this many steps (0: "
                  "none)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000000));
  cmd->add_option("--resume", a->resume, "Continue the run of this checkpoint (NAME.checkpoint.json)")
      ->check(CLI::ExistingFile)
      ->excludes("--start");
  cmd->add_option("--write-colmap", a->write_colmap,
                  "Also write the training views at the working size and the start points as a COLMAP folder (the "
                  "same start for another trainer)");
  cmd->add_option("--background", a->background,
                  "The colour behind the splats, r,g,b in [0, 1], in training, scores and previews (to score another "
                  "trainer's splats: the colour it trained with)")
      ->delimiter(',')
      ->expected(3)
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--previews", a->previews, "Folder of the previews (default: OUT's name + -previews)");
  cmd->add_flag("--json", a->json, "Print the report as JSON");
  add_runtime_options(cmd, a->runtime);
  // The shared scene and runtime options that mean nothing here: every view trains whole (no
  // object masks; --eval holds out its own), and no network runs.
  for (const char* unused : {"--masks", "--alpha-masks", "--hold-out-every", "--precision"})
    cmd->remove_option(cmd->get_option(unused));
  cmd->callback([a] { run(*a); });
}

}  // namespace ii::cli
