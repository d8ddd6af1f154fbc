#pragma once
// Choosing the context (input) views of a scene: by name, or automatically.
#include <string>
#include <vector>

#include "data/scene.h"

namespace ii {

// Indices into scene.views for the given names, in the given order (first = reference).
std::vector<int> context_views_by_name(const Scene& scene, const std::vector<std::string>& names);

// Automatic choice: the reference is the view whose camera centre is nearest the middle of
// the capture; the others span the largest triangle (for 3 others; farthest-point sampling
// for other counts) of camera centres projected on the capture's best-fit plane.
std::vector<int> select_context_views(const Scene& scene, int count = 4);

}  // namespace ii
