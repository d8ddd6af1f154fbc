#include "model/default_model.h"

#include "common/error.h"

// Symbols from the assembler file CMake generates around models/default.safetensors.
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

Checkpoint checkpoint_or_default(const std::string& path) {
  return path.empty() ? default_checkpoint() : read_checkpoint(path);
}

}  // namespace ii
