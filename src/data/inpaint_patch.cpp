// Exemplar-based inpainting through CImg's inpaint_patch (Debian's cimg-dev, header only): the
// hole filled from its border inward with patches copied from the rest of the picture, so that
// texture and edges continue where OpenCV's diffusion methods draw a radial smear. Alone in this
// file: CImg is one large header.
#define cimg_display 0
#define cimg_verbosity 0
#define cimg_plugin "plugins/inpaint.h"
#include <CImg.h>

#include <algorithm>
#include <cstdint>
#include <optional>

#include "common/error.h"
#include "data/inpaint2d.h"

namespace ii {

namespace {

// The hole's bounding box grown by its larger side (at least 32 pixels) each way, within the
// picture: the patches are looked up near the hole, so the rest of the picture is not read.
struct Window {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

std::optional<Window> hole_window(const Image& mask) {
  Window b{mask.width, mask.height, -1, -1};
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x)
      if (mask.at(y, x) > 0.5f) b = {std::min(b.x0, x), std::min(b.y0, y), std::max(b.x1, x + 1), std::max(b.y1, y + 1)};
  if (b.x1 < 0) return std::nullopt;
  const int grow = std::max({32, b.x1 - b.x0, b.y1 - b.y0});
  return Window{std::max(0, b.x0 - grow), std::max(0, b.y0 - grow), std::min(mask.width, b.x1 + grow),
                std::min(mask.height, b.y1 + grow)};
}

}  // namespace

Image inpaint_patches(const Image& full, const Image& full_mask) {
  const std::optional<Window> window = hole_window(full_mask);
  if (!window) return full;
  const int w = window->x1 - window->x0, h = window->y1 - window->y0;
  auto rgb_at = [&](int y, int x, int c) { return full.at(y + window->y0, x + window->x0, c); };
  auto hole_at = [&](int y, int x) { return full_mask.at(y + window->y0, x + window->x0) > 0.5f; };
  // Patches of 9 pixels looked up within 16 of the one to fill (half as far at each step out):
  // 0.8 s for SPIn-NeRF scene 1's 35 k-pixel hole at 1008 x 567 on one core. Outside the hole
  // the picture is returned as it was, bit for bit.
  constexpr unsigned kPatch = 9, kLookup = 16;
  constexpr float kLookupFactor = 0.5f;
  cimg_library::CImg<float> picture(w, h, 1, 3);
  cimg_library::CImg<unsigned char> hole(w, h, 1, 1, 0);
  size_t known = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) picture(x, y, 0, c) = std::clamp(rgb_at(y, x, c), 0.f, 1.f) * 255.f;
      hole(x, y) = hole_at(y, x) ? 1 : 0;
      known += hole(x, y) == 0;
    }
  // Nothing to copy from: no patch search (CImg would find no source).
  if (known == 0) return inpaint_classical(full, full_mask, ClassicalInpainter::Telea);
  try {
    picture.inpaint_patch(hole, kPatch, kLookup, kLookupFactor, 1, 0, 0.f);  // no blending of patches
  } catch (const cimg_library::CImgException& e) {
    fail("patch inpainting of a {}x{} picture: {}", w, h, e.what());
  }
  Image out = full;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (hole_at(y, x))
        for (int c = 0; c < 3; ++c)
          out.at(y + window->y0, x + window->x0, c) = std::clamp(picture(x, y, 0, c) / 255.f, 0.f, 1.f);
  return out;
}

}  // namespace ii
