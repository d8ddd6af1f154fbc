#pragma once
// The default model: small weights trained by us (models/default.safetensors, see
// models/MODEL_CARD.md), compiled into the library so that every command runs without a
// checkpoint file.
#include <string>

#include "model/checkpoint.h"

namespace ii {

// Whether this build holds the default model (it does whenever models/default.safetensors
// was present at configure time).
bool has_default_model();

// The default model as a checkpoint; throws Error when the build has none.
Checkpoint default_checkpoint();

// The name the default model goes by in messages and run.json.
constexpr const char* kDefaultModelName = "<embedded default model>";

// `path` when given, else the default model.
Checkpoint checkpoint_or_default(const std::string& path, bool map_weights = false);

// What --checkpoint names in every command: "" or "auto", InstaInpaint's released checkpoint when
// the cache holds it verified (instainpaint models get instainpaint), else the default model;
// "default", the default model; a catalogue name, its cached file; else a file. The default
// model is "".
std::string resolve_checkpoint(const std::string& value);

}  // namespace ii
