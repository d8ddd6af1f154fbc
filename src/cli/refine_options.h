#pragma once
// `--refine STEPS` for the commands that run the network (infer, eval).
#include <CLI/CLI.hpp>

#include "refine/refine.h"

namespace ii::cli {

void add_refine_option(CLI::App* cmd, int& steps);
// Refinement of `steps` steps with a progress line (loss, ETA) on stderr.
RefineOptions refine_options(int steps);

}  // namespace ii::cli
