#pragma once
// Gaussians that another view sees through. One Gaussian per pixel puts a pixel on a depth edge
// between the near and the far surface (its depth a blend of both: a "flying pixel"); from another
// camera it hangs in front of what that camera sees, and four views' such pixels smear an object
// across the room (the demo's room, 128 rows: seen from the other context views, 14-27 % of each
// view's Gaussians lay more than 10 % in front of the true surface there). Each view's Gaussians on a
// depth edge of its own depth map that land in front of another view's depth there (outside that
// view's mask, where its depth is the network's guess) keep a fraction of their opacity.
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "camera/camera.h"
#include "data/preprocess.h"
#include "gaussians/gaussians.h"
#include "geometry/visibility.h"

namespace ii {

struct FloaterOptions {
  // The opacity a floater keeps (1: none faded, the paper's Gaussians). 0 drops them and loses
  // the statue 0.2 dB (its far background's depths disagree between views); 0.3 and 0.5 lose
  // nothing held out (2026-11-28, 279a7e8; docs/usage.md, "The steps after the network, measured").
  double fade = 0.3;
  double tolerance = 0.1;  // in front of another view's depth by more than this fraction
  double edge = 0.15;      // on a depth edge: the log depths of its 3 x 3 pixels span more than this
};

// Fades the floaters of `maps` (the network's output, B = 1, after any depth alignment) in place:
// `views` and `cameras` are the context views (their masks) and their cameras in the maps' frame.
// Returns how many Gaussians were faded.
int64_t fade_floaters(GaussianMaps& maps, const std::vector<PreparedView>& views, const std::vector<Camera>& cameras,
                      const FloaterOptions& options);

// What run.json and metrics.json record of it.
nlohmann::json describe_floaters(const FloaterOptions& options, int64_t faded);

}  // namespace ii
