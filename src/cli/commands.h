#pragma once
// Each subcommand registers itself on the app; the command bodies are thin wrappers over
// the library.
#include <filesystem>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "data/scene.h"

namespace ii::cli {

void add_scene_info_command(CLI::App& app);
void add_capture_command(CLI::App& app);
void add_prepare_command(CLI::App& app);
void add_infer_command(CLI::App& app);
void add_bench_command(CLI::App& app);
void add_convert_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_synth_command(CLI::App& app);
void add_metrics_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_train_command(CLI::App& app);
void add_masks_command(CLI::App& app);
void add_serve_command(CLI::App& app);
void add_fill_command(CLI::App& app);
void add_reconstruct_command(CLI::App& app);
void add_segment_command(CLI::App& app);
void add_inpaint_command(CLI::App& app);
void add_models_command(CLI::App& app);

// An optional file option's value: none when it was left empty.
inline std::optional<std::filesystem::path> optional_path(const std::string& s) {
  if (s.empty()) return std::nullopt;
  return std::filesystem::path(s);
}

// Options shared by every command that reads a scene.
void add_scene_options(CLI::App* cmd, std::string& scene_dir, SceneOptions& options);

}  // namespace ii::cli
