#pragma once
// Model weights on disk: official `.pth` checkpoints (read without Python through the
// restricted unpickler in io/pth.h) and safetensors with the official key names.
// Loading normalises key names (module prefix, DDP's `module.`), folds weight-norm pairs
// into plain weights, and infers the architecture from the shapes.
#include <filesystem>
#include <map>
#include <string>

#include <nlohmann/json.hpp>
#include "common/torch.h"

#include "io/safetensors.h"
#include "model/config.h"
#include "model/network.h"

namespace ii {

using StateDict = std::map<std::string, torch::Tensor>;

struct Checkpoint {
  StateDict state;           // official names, weight norm folded, float32
  ModelConfig config;        // inferred from shapes (+ stored config/arguments)
  std::string format;        // "pth" or "safetensors"
  nlohmann::json extra;      // stored training arguments / metadata, as plain data
  int folded_weight_norms = 0;
  // With keep_weight_norm: the weight-norm tensors as stored (`...weight_g`, `...weight_v`,
  // official names), so that training continues in the file's own parametrisation.
  StateDict weight_norm;
};

// Reads a checkpoint file (format from its content, not its extension). `map_weights`: a
// safetensors file's float32 weights stay in its read-only mapping (map_safetensors_tensors),
// for a caller that copies them on at once (to a GPU) and never writes into them.
Checkpoint read_checkpoint(const std::filesystem::path& path, bool keep_weight_norm = false,
                           bool map_weights = false);
// A checkpoint from parsed safetensors (`path` names it in messages).
Checkpoint checkpoint_from_safetensors(SafetensorsFile file, const std::filesystem::path& path,
                                      bool keep_weight_norm = false);

// A Network of the checkpoint's architecture holding its weights.
Network network_from_checkpoint(const Checkpoint& checkpoint, const std::string& source);
// The same, taking the checkpoint's tensors over (no copy of the weights).
Network network_from_checkpoint(Checkpoint&& checkpoint, const std::string& source);

// read_checkpoint + a Network of the inferred architecture with the weights loaded.
Network load_network(const std::filesystem::path& path);

// Writes safetensors with the official key names: weight-normed layers as `weight_g`
// (row norms) and `weight_v` (the weight itself), which fold back to the same weight; the
// architecture goes into `__metadata__.config`. Atomic.
void save_safetensors_checkpoint(const std::filesystem::path& path, const Network& network,
                                 const nlohmann::json& extra_metadata = {});

// Architecture from official-layout shapes; `hints` may carry num_heads etc.
ModelConfig infer_config(const StateDict& state, const nlohmann::json& hints, const std::string& source);

// Every tensor of a safetensors file, under its stored name.
StateDict read_safetensors_tensors(const std::filesystem::path& path);

// Key normalisation and weight-norm folding on a raw state dict (exposed for tests).
// `weight_norm`, when given, receives the g and v tensors before folding.
StateDict normalize_state_dict(const StateDict& raw, int* folded = nullptr, StateDict* weight_norm = nullptr);

}  // namespace ii
