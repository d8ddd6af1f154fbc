#include "render/frames.h"

#include <fmt/format.h>

#include "common/stopwatch.h"
#include "io/image.h"
#include "render/visualize.h"
#include "tensor/image_tensor.h"

namespace ii {

double render_frames(const GaussianSet& gaussians, const std::vector<NamedCamera>& cameras, const RenderOptions& options,
                     const FrameFolders& folders, const std::function<void(int, int)>& progress) {
  for (const auto* folder : {&folders.rgb, &folders.depth, &folders.alpha})
    if (!folder->empty()) std::filesystem::create_directories(*folder);
  VideoDepthColours depth_colours;
  double render_ms = 0;
  const int n = static_cast<int>(cameras.size());
  for (int i = 0; i < n; ++i) {
    RenderCamera rc;
    rc.camera = cameras[i].camera;
    Stopwatch frame;
    const RenderOutput r = render(gaussians, rc, options);
    const Image rgb = image_from_hwc(r.rgb);  // on the CPU: the frame is done
    render_ms += frame.ms();
    const std::string file = fmt::format("{:04d}.png", i);
    write_png(folders.rgb / file, rgb);
    if (!folders.depth.empty()) write_png(folders.depth / file, depth_colours(r.depth, r.alpha));
    if (!folders.alpha.empty()) write_png(folders.alpha / file, image_from_hwc(r.alpha));
    if (progress) progress(i + 1, n);
  }
  return render_ms;
}

}  // namespace ii
