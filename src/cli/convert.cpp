// `instainpaint convert`: official .pth (or safetensors) -> safetensors with official key
// names; or a splat file to another splat format (PLY, compressed PLY, SPZ), by the names.
#include <fmt/core.h>

#include "cli/commands.h"
#include "common/stopwatch.h"
#include "io/splat_file.h"
#include "model/checkpoint.h"

namespace ii::cli {

namespace {

void convert_checkpoint(const std::string& in, const std::string& out) {
  const Checkpoint ck = read_checkpoint(in);
  const Network net = network_from_checkpoint(ck, in);
  nlohmann::json meta;
  meta["source"] = std::filesystem::path(in).filename().string();
  if (ck.extra.contains("args")) meta["training_args"] = ck.extra["args"].dump();
  save_safetensors_checkpoint(out, net, meta);
  fmt::print("{} ({}, {} model: {} blocks, width {}, {} parameters, {} weight-norm pairs folded) -> {}\n", in,
             ck.format, ck.config.preset, ck.config.blocks, ck.config.embed_dim, ck.config.parameter_count(),
             ck.folded_weight_norms, out);
}

void convert_splats(const std::string& in, const std::string& out) {
  const SplatFormat to = splat_format_of(out);  // a bad output name fails before the reading
  Stopwatch watch;
  const SplatCloud cloud = read_splats(in);
  const double read_ms = watch.lap();
  write_splats(out, cloud);
  const double write_ms = watch.lap();
  const auto in_bytes = std::filesystem::file_size(in), out_bytes = std::filesystem::file_size(out);
  const double n = std::max<double>(1, static_cast<double>(cloud.size()));
  fmt::print("{} ({} splats, SH degree {}, {:.1f} bytes each) -> {} ({}, {:.1f} bytes each, {:.2f}x the input); read "
             "{:.0f} ms, write {:.0f} ms\n",
             in, cloud.size(), cloud.sh_degree(),
             in_bytes / n, out, splat_format_name(to), out_bytes / n, static_cast<double>(in_bytes) / std::max<double>(1, out_bytes),
             read_ms, write_ms);
}

}  // namespace

void add_convert_command(CLI::App& app) {
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand(
      "convert", "Convert a checkpoint (.pth or safetensors) to safetensors with official key names, or a splat file "
                 "to another splat format");
  cmd->add_option("IN", *in, "Input checkpoint, or splat file (.ply, .compressed.ply, .spz, .sog, meta.json)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("OUT", *out, "Output .safetensors file, or splat file (the format follows the name)")->required();
  cmd->footer(
      "Examples:\n"
      "  instainpaint convert exp_ins+random+3d_121_multimask.pth release.safetensors\n"
      "  instainpaint convert out/gaussians.ply out/gaussians.spz\n"
      "  instainpaint convert scene.spz scene.compressed.ply\n"
      "  instainpaint convert scene.sog scene.ply");
  cmd->callback([in, out] {
    if (is_splat_file_name(*in) || is_splat_file_name(*out))
      convert_splats(*in, *out);
    else
      convert_checkpoint(*in, *out);
  });
}

}  // namespace ii::cli
