#include "eval/truth_reference.h"

#include <algorithm>

#include "common/error.h"

namespace ii {

std::optional<TruthReference> take_truth_reference(Scene& scene, const std::string& name) {
  if (name.empty()) return std::nullopt;
  const auto found = std::find_if(scene.test_views.begin(), scene.test_views.end(),
                                  [&](const View& v) { return v.name == name && !v.shows_object; });
  if (found == scene.test_views.end()) return std::nullopt;
  if (!found->mask_path && !found->mask_from_alpha)
    fail("{}: test view {} has no mask in test_label/: as the reference its mask is the region", scene.root.string(),
         name);
  TruthReference truth{found->name, found->image_path};
  // The pose normalisation is over every camera, inputs and test views alike: moving one between
  // the two lists leaves it as it was.
  scene.views.push_back(*found);
  scene.test_views.erase(found);
  return truth;
}

}  // namespace ii
