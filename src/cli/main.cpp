// instainpaint: feed-forward 3D inpainting. Thin command-line front end over the library.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>

#include "cli/commands.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "common/memory.h"

int main(int argc, char** argv) {
  CLI::App app{
      "instainpaint: remove an object from a 3D scene in one forward pass.\n"
      "Give posed photos, a mask of the object in each, and one photo where the object was\n"
      "already painted out by a 2D inpainter; get 3D Gaussians without the object."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "instainpaint 0.1.0");
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "Print debug messages");
  ii::keep_large_allocations();
  // Messages on stderr: stdout carries what a command prints as its result (--json, tables).
  spdlog::set_default_logger(spdlog::stderr_color_mt("instainpaint"));
  spdlog::set_pattern("%^%l%$: %v");
  // Set before parsing: subcommands run inside parse().
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "-v" || std::string(argv[i]) == "--verbose")
      spdlog::set_level(spdlog::level::debug);

  ii::cli::add_scene_info_command(app);
  ii::cli::add_capture_command(app);
  ii::cli::add_prepare_command(app);
  ii::cli::add_masks_command(app);
  ii::cli::add_infer_command(app);
  ii::cli::add_fill_command(app);
  ii::cli::add_reconstruct_command(app);
  ii::cli::add_segment_command(app);
  ii::cli::add_inpaint_command(app);
  ii::cli::add_models_command(app);
  ii::cli::add_convert_command(app);
  ii::cli::add_render_command(app);
  ii::cli::add_synth_command(app);
  ii::cli::add_bench_command(app);
  ii::cli::add_metrics_command(app);
  ii::cli::add_eval_command(app);
  ii::cli::add_train_command(app);
  ii::cli::add_serve_command(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const ii::Error& e) {
    std::fflush(stdout);
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::fflush(stdout);
    std::cerr << "error: " << e.what() << "\n";
    return 2;
  }
  // After a GPU command: out without LibTorch's CUDA teardown (freeing the cached device memory,
  // destroying the context), which the user would wait for. Every file is written by now.
  if (ii::cli::gpu_was_set_up()) {
    std::fflush(nullptr);
    spdlog::shutdown();
    std::_Exit(0);
  }
  return 0;
}
