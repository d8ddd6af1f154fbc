#pragma once
// `--refine STEPS` and `--refine-sh-degree` for the commands that run the network (infer, eval).
#include <CLI/CLI.hpp>

#include "refine/refine.h"

namespace ii::cli {

struct RefineArgs {
  int steps = 0;  // 0 = the feed-forward result
  int sh_degree = 0;
};

void add_refine_options(CLI::App* cmd, RefineArgs& args);
// The refinement asked for, with a progress line (loss, ETA) on stderr.
RefineOptions refine_options(const RefineArgs& args);

}  // namespace ii::cli
