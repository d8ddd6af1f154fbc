// The built-in 2D inpainters: the names they answer to, that they change nothing outside the
// hole, and what each does to an edge through the hole (patches continue it, diffusion blurs it).
#include <gtest/gtest.h>

#include <cmath>

#include "common/error.h"
#include "data/inpaint2d.h"

namespace ii {
namespace {

// Two regions meeting at a vertical edge (dark left of column `edge`, light right of it), tinted
// slightly per row so that no two rows are alike.
Image two_sides(int width, int height, int edge) {
  Image image(width, height, 3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const float v = x < edge ? 0.15f : 0.85f;
      image.at(y, x, 0) = v;
      image.at(y, x, 1) = v;
      image.at(y, x, 2) = 0.5f + 0.002f * static_cast<float>(y);
    }
  return image;
}

Image square(int width, int height, int x0, int y0, int size) {
  Image mask(width, height, 1);
  for (int y = y0; y < y0 + size; ++y)
    for (int x = x0; x < x0 + size; ++x) mask.at(y, x) = 1.f;
  return mask;
}

// Mean absolute difference to `truth` over the mask's pixels.
double hole_error(const Image& filled, const Image& truth, const Image& mask) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x)
      if (mask.at(y, x) > 0.5f) {
        for (int c = 0; c < 3; ++c) sum += std::abs(filled.at(y, x, c) - truth.at(y, x, c));
        n += 3;
      }
  return sum / n;
}

TEST(Inpaint2d, NamesRoundTrip) {
  for (const ClassicalInpainter m : {ClassicalInpainter::Telea, ClassicalInpainter::NavierStokes, ClassicalInpainter::Patches})
    EXPECT_EQ(parse_inpainter(inpainter_name(m)), m);
  EXPECT_EQ(inpainter_name(ClassicalInpainter::Patches), "patch");
  try {
    parse_inpainter("lama");
    FAIL() << "an unknown name is refused";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "unknown 2D inpainter 'lama' (telea, ns or patch)");
  }
}

TEST(Inpaint2d, PatchesKeepAnEdgeThatDiffusionBlurs) {
  const Image truth = two_sides(96, 80, 47);
  const Image mask = square(96, 80, 36, 28, 24);  // the edge runs through the hole's middle
  Image holed = truth;
  for (int y = 0; y < 80; ++y)
    for (int x = 0; x < 96; ++x)
      if (mask.at(y, x) > 0.5f)
        for (int c = 0; c < 3; ++c) holed.at(y, x, c) = 0.f;  // what the hole held is not read
  const Image patches = inpaint_classical(holed, mask, ClassicalInpainter::Patches);
  const Image telea = inpaint_classical(holed, mask, ClassicalInpainter::Telea);
  const double patch_error = hole_error(patches, truth, mask), telea_error = hole_error(telea, truth, mask);
  EXPECT_LT(patch_error, 0.02) << "the edge goes on through the hole";
  EXPECT_GT(telea_error, 2 * patch_error) << "Telea blurs it (error " << telea_error << ")";
  // Outside the hole the picture is the one given, bit for bit; the same input gives the same fill.
  for (int y = 0; y < 80; ++y)
    for (int x = 0; x < 96; ++x) {
      if (mask.at(y, x) > 0.5f) continue;
      for (int c = 0; c < 3; ++c) ASSERT_EQ(patches.at(y, x, c), holed.at(y, x, c)) << x << "," << y;
    }
  EXPECT_EQ(inpaint_classical(holed, mask, ClassicalInpainter::Patches).pixels, patches.pixels);
}

TEST(Inpaint2d, PatchesWithNothingOrEverythingMasked) {
  const Image picture = two_sides(32, 24, 16);
  EXPECT_EQ(inpaint_classical(picture, Image(32, 24, 1), ClassicalInpainter::Patches).pixels, picture.pixels);
  const Image all = inpaint_classical(picture, Image(32, 24, 1, 1.f), ClassicalInpainter::Patches);
  EXPECT_EQ(all.width, 32);  // nothing to copy from: Telea's answer, no failure
  EXPECT_EQ(all.height, 24);
}

}  // namespace
}  // namespace ii
