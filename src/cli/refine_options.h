#pragma once
// `--refine` (fast, balanced, best, a time or a number of steps), `--refine-sh-degree`,
// `--refine-exposure`, `--refine-position-rate` and `--refine-without` for the commands that run the network (infer, eval).
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "refine/refine.h"

namespace ii::cli {

struct RefineArgs {
  std::string setting = "0";  // 0 = the feed-forward result
  int sh_degree = 0;
  std::vector<std::string> without;  // parts switched off: cover, densify, coarse-to-fine
  bool exposure = false;
  double position_rate = 0;  // × 3DGS's position learning rate; 0: RefineOptions' default
};

void add_refine_options(CLI::App* cmd, RefineArgs& args);
// The refinement asked for, with a progress line (loss, Gaussians, ETA) on stderr.
RefineOptions refine_options(const RefineArgs& args);
// The progress of an optimisation as one line on stderr rewritten in place (a terminal), or a log
// line per tenth of the run: "WHAT 42%  step 1200  loss 0.0412  180000 Gaussians  ETA 95 s".
std::function<void(const RefineProgress&)> progress_line(const std::string& what);
// The loss curve of a refinement report (refinement_report()) as OUT/refine-loss.png, named in
// the report as "loss_chart".
void write_loss_chart(const std::filesystem::path& out, nlohmann::json& report);

}  // namespace ii::cli
