#pragma once
// Image sizes given on the command line: "512" (square) or "904x512" (width x height).
#include <string>

namespace ii::cli {

struct InputSize {
  int width = 0, height = 0;
};

// The size `text` names; an Error naming `option` and the text when it is not one, or is
// outside 8..8192 pixels.
InputSize parse_size(const std::string& text, const std::string& option);

}  // namespace ii::cli
