#pragma once
// The protocol of the paper's table "ground-truth image as reference": an object-free test view
// is taken as the reference view. Its own photo is the reference (the region exactly as the
// place holds it, so a learned 2D inpainter's valid but different content is not what is
// measured), its test mask is the region, and it is no longer scored: the other test views
// measure the geometry and coverage of the region's new content.
#include <filesystem>
#include <optional>
#include <string>

#include "data/scene.h"

namespace ii {

struct TruthReference {
  std::string view;             // the test view taken as the reference
  std::filesystem::path photo;  // its photo, the reference image
};

// When `name` is an object-free test view of `scene`, moves it to the input views and returns
// it; nullopt otherwise (an input view, or empty). An Error when that test view has no mask.
std::optional<TruthReference> take_truth_reference(Scene& scene, const std::string& name);

}  // namespace ii
