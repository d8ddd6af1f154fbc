#pragma once
// Classical 2D inpainting (OpenCV Telea), used to make a reference image when the user has
// none from a learned 2D inpainter, and as a baseline in evaluation.
#include "io/image.h"

namespace ii {

// Fills pixels where mask == 1. `radius` is the neighbourhood considered, in pixels.
Image inpaint_telea(const Image& rgb, const Image& mask, double radius = 5.0);

}  // namespace ii
