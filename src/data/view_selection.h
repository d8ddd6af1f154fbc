#pragma once
// Choosing the context (input) views of a scene: by name, or automatically.
#include <optional>
#include <string>
#include <vector>

#include "data/scene.h"

namespace ii {

// The index into scene.views of the input view `name`; otherwise an error "unknown <what>
// 'name'" listing the views (and saying so when it is a test view).
int input_view_index(const Scene& scene, const std::string& name, const std::string& what = "view");

// Indices into scene.views for the given names, in the given order (first = reference).
std::vector<int> context_views_by_name(const Scene& scene, const std::vector<std::string>& names);

// Automatic choice: the reference is `reference_view` (an index into scene.views) when given,
// else the view whose camera centre is nearest the middle of the capture; the others, among the
// views looking within 30 degrees of the reference's direction (all of a forward-facing capture's;
// on a capture around its object, the reference's neighbours, as the paper's context is), span
// the largest triangle (for 3 others; farthest-point sampling for other counts) of camera
// centres projected on the capture's best-fit plane.
std::vector<int> select_context_views(const Scene& scene, int count = 4, std::optional<int> reference_view = {});

}  // namespace ii
