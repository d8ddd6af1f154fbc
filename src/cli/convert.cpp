// `instainpaint convert`: official .pth (or safetensors) -> safetensors with official key names.
#include <fmt/core.h>

#include "cli/commands.h"
#include "model/checkpoint.h"

namespace ii::cli {

void add_convert_command(CLI::App& app) {
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand("convert", "Convert a checkpoint (.pth or safetensors) to safetensors with official key names");
  cmd->add_option("IN", *in, "Input checkpoint")->required()->check(CLI::ExistingFile);
  cmd->add_option("OUT", *out, "Output .safetensors file")->required();
  cmd->footer("Example: instainpaint convert exp_ins+random+3d_121_multimask.pth release.safetensors");
  cmd->callback([in, out] {
    const Checkpoint ck = read_checkpoint(*in);
    const Network net = network_from_checkpoint(ck, *in);
    nlohmann::json meta;
    meta["source"] = std::filesystem::path(*in).filename().string();
    if (ck.extra.contains("args")) meta["training_args"] = ck.extra["args"].dump();
    save_safetensors_checkpoint(*out, net, meta);
    fmt::print("{} ({}, {} model: {} blocks, width {}, {} parameters, {} weight-norm pairs folded) -> {}\n", *in,
               ck.format, ck.config.preset, ck.config.blocks, ck.config.embed_dim, ck.config.parameter_count(),
               ck.folded_weight_norms, *out);
  });
}

}  // namespace ii::cli
