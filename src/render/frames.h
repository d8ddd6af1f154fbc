#pragma once
// A camera list rendered to numbered PNG frames (0000.png, ...): `render` and the server's
// orbit video both go through here.
#include <filesystem>
#include <functional>
#include <vector>

#include "camera/trajectory.h"
#include "gaussians/gaussians.h"
#include "render/rasterizer.h"

namespace ii {

struct FrameFolders {
  std::filesystem::path rgb;    // always written
  std::filesystem::path depth;  // empty: none (else colour-mapped depth, one range for the whole sequence)
  std::filesystem::path alpha;  // empty: none
};

// Renders every camera in order on the Gaussians' device and writes its frames (folders made
// as needed); `progress(done, total)` after each. Returns the milliseconds spent rendering
// (each frame until its image is on the CPU), without the PNG writing.
double render_frames(const GaussianSet& gaussians, const std::vector<NamedCamera>& cameras, const RenderOptions& options,
                     const FrameFolders& folders, const std::function<void(int, int)>& progress = {});

}  // namespace ii
