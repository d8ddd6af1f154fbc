#include "cli/refine_options.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <memory>

#include <spdlog/spdlog.h>

#include "common/stopwatch.h"

namespace ii::cli {

void add_refine_options(CLI::App* cmd, RefineArgs& args) {
  cmd->add_option("--refine", args.steps,
                  "Optimise the predicted Gaussians for this many steps against every view of the scene (outside "
                  "the object masks; the reference everywhere); 0 = the feed-forward result, as the paper")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  cmd->add_option("--refine-sh-degree", args.sh_degree,
                  "With --refine: 0 = one colour per Gaussian; 1-3 = fit view-dependent colour (spherical "
                  "harmonics of this degree, written to the PLY's f_rest)")
      ->capture_default_str()
      ->check(CLI::Range(0, 3));
}

RefineOptions refine_options(const RefineArgs& args) {
  RefineOptions o;
  o.steps = args.steps;
  o.sh_degree = args.sh_degree;
  auto watch = std::make_shared<Stopwatch>();
  // A terminal gets one line rewritten in place; a log file a line per tenth of the run.
  const bool tty = ::isatty(::fileno(stderr));
  o.progress = [watch, tty](int done, int total, double loss) {
    const double eta = watch->ms() / done * (total - done) / 1000;
    if (tty) {
      std::fprintf(stderr, "\rrefine %d/%d  loss %.4f  ETA %.0f s\033[K", done, total, loss, eta);
      if (done == total) std::fprintf(stderr, "\n");
    } else if (done == 1 || done == total || done % std::max(1, total / 10) == 0) {
      spdlog::info("refine {}/{}  loss {:.4f}  ETA {:.0f} s", done, total, loss, eta);
    }
  };
  return o;
}

}  // namespace ii::cli
