#include "cli/refine_options.h"

#include <unistd.h>

#include <cstdio>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "data/chart.h"
#include "io/image.h"

namespace ii::cli {

namespace {
// What `--refine` alone means: the best result in about 9 minutes on 2 CPU cores.
constexpr const char* kDefaultRefinement = "balanced";
}  // namespace

void add_refine_options(CLI::App* cmd, RefineArgs& args) {
  cmd->add_option("--refine", args.setting,
                  "Optimise the predicted Gaussians against every view of the scene (outside the object masks; the "
                  "reference everywhere), 3DGS-style with densification: fast (1 minute), balanced (9 minutes), best "
                  "(20 minutes), a time (90s, 2m) or a number of steps. --refine alone: balanced; without it (or 0): "
                  "the feed-forward result, as the paper")
      ->expected(0, 1)
      ->default_str(kDefaultRefinement)  // the value of `--refine` given alone
      ->check([](const std::string& text) {
        try {
          refine_setting(text.empty() ? kDefaultRefinement : text);
          return std::string();
        } catch (const Error& e) {
          return std::string(e.what());
        }
      });
  cmd->add_option("--refine-sh-degree", args.sh_degree,
                  "With --refine: 0 = one colour per Gaussian; 1-3 = fit view-dependent colour (spherical "
                  "harmonics of this degree, written to the PLY's f_rest)")
      ->capture_default_str()
      ->check(CLI::Range(0, 3));
  cmd->add_flag("--refine-exposure", args.exposure,
                "With --refine: correct each view's colours (an affine colour map per view, reported in the run's "
                "JSON), for phone captures whose exposure or white balance changes between photos");
  cmd->add_option("--refine-position-rate", args.position_rate,
                  "With --refine: the position learning rate at the start, in multiples of 3DGS's (default 30: the "
                  "prediction's surfaces are near; about 10 suits scenes like its synthetic training rooms, where "
                  "the geometry is right and a high rate only blurs; 300 suited the network's raw depth)")
      ->check(CLI::Range(0.01, 10000.0));
  cmd->add_option("--refine-without", args.without,
                  "With --refine: parts of the optimisation to switch off: cover (new Gaussians where no Gaussian "
                  "covers a view), densify (clone, split, prune, opacity resets), reset (the opacity resets alone), "
                  "coarse-to-fine, masks (each view's mask fitted to what the prediction draws there; without, "
                  "masked pixels are free)")
      ->delimiter(',')
      ->check(CLI::IsMember({"cover", "densify", "reset", "coarse-to-fine", "masks"}));
}

RefineOptions refine_options(const RefineArgs& args) {
  RefineOptions o = refine_setting(args.setting.empty() ? kDefaultRefinement : args.setting);
  o.sh_degree = args.sh_degree;
  o.exposure = args.exposure;
  if (args.position_rate > 0) o.position_lr = args.position_rate * kGaussianSplattingPositionLr;
  for (const std::string& part : args.without) {
    if (part == "cover") o.cover = false;
    if (part == "densify") o.densify.enabled = false;
    if (part == "reset") o.opacity_resets.clear();
    if (part == "coarse-to-fine") o.coarse_to_fine = false;
    if (part == "masks") o.start_in_masks = false;
  }
  o.progress = progress_line("refine");
  return o;
}

std::function<void(const RefineProgress&)> progress_line(const std::string& what) {
  // A terminal gets one line rewritten in place; a log file a line per tenth of the run.
  const bool tty = ::isatty(::fileno(stderr));
  auto last_tenth = std::make_shared<int>(-1);
  return [tty, last_tenth, what](const RefineProgress& p) {
    const bool done = p.fraction >= 1;
    if (tty) {
      std::fprintf(stderr, "\r%s %3.0f%%  step %d  loss %.4f  %lld Gaussians  ETA %.0f s\033[K", what.c_str(),
                   100 * p.fraction, p.step, p.loss, static_cast<long long>(p.gaussians), p.eta_s);
      if (done) std::fprintf(stderr, "\n");
    } else if (static_cast<int>(p.fraction * 10) > *last_tenth || p.step == 1) {
      *last_tenth = static_cast<int>(p.fraction * 10);
      spdlog::info("{} {:.0f}%  step {}  loss {:.4f}  {} Gaussians  ETA {:.0f} s", what, 100 * p.fraction, p.step,
                   p.loss, p.gaussians, p.eta_s);
    }
  };
}

void write_loss_chart(const std::filesystem::path& out, nlohmann::json& report) {
  const std::vector<double> losses = report["losses"].get<std::vector<double>>();
  const std::string title = fmt::format("refinement loss per step ({}, {:.0f} s)", report["length"].get<std::string>(),
                                        report["seconds"].get<double>());
  std::filesystem::create_directories(out);
  write_png(out / "refine-loss.png", line_chart(losses, title));
  report["loss_chart"] = "refine-loss.png";
}

}  // namespace ii::cli
