#include "model/default_model.h"

#include "common/error.h"
#include "models/cache.h"

// Symbols of the assembler file CMake generates around models/default.safetensors; it defines
// INSTAINPAINT_DEFAULT_MODEL for this file only (cmake/default_model.cmake). The references
// must be strong: a weak one would not pull the assembler object out of the static library.
#ifdef INSTAINPAINT_DEFAULT_MODEL
extern "C" const unsigned char ii_default_model_begin[];
extern "C" const unsigned char ii_default_model_end[];
#endif

namespace ii {

bool has_default_model() {
#ifdef INSTAINPAINT_DEFAULT_MODEL
  return true;
#else
  return false;
#endif
}

Checkpoint default_checkpoint() {
#ifdef INSTAINPAINT_DEFAULT_MODEL
  const auto size = static_cast<size_t>(ii_default_model_end - ii_default_model_begin);
  return checkpoint_from_safetensors(parse_safetensors(ii_default_model_begin, size, kDefaultModelName),
                                     kDefaultModelName);
#else
  fail("this build has no default model (models/default.safetensors was absent when it was configured): "
       "give --checkpoint");
#endif
}

Checkpoint checkpoint_or_default(const std::string& path, bool map_weights) {
  return path.empty() ? default_checkpoint() : read_checkpoint(path, false, map_weights);
}

std::string resolve_checkpoint(const std::string& value) {
  if (value == "default") return "";
  const ModelChoice choice = choose_model(ModelRole::Checkpoint, value.empty() ? "auto" : value);
  return choice.file ? choice.file->string() : "";
}

}  // namespace ii
