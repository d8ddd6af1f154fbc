#include "cli/refine_options.h"

#include <cstdio>
#include <memory>

#include "common/stopwatch.h"

namespace ii::cli {

void add_refine_option(CLI::App* cmd, int& steps) {
  cmd->add_option("--refine", steps,
                  "Optimise the predicted Gaussians for this many steps against every view of the scene (outside "
                  "the object masks; the reference everywhere); 0 = the feed-forward result, as the paper")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
}

RefineOptions refine_options(int steps) {
  RefineOptions o;
  o.steps = steps;
  auto watch = std::make_shared<Stopwatch>();
  o.progress = [watch](int done, int total, double loss) {
    const double eta = watch->ms() / done * (total - done) / 1000;
    std::fprintf(stderr, "\rrefine %d/%d  loss %.4f  ETA %.0f s ", done, total, loss, eta);
    if (done == total) std::fprintf(stderr, "\n");
  };
  return o;
}

}  // namespace ii::cli
