#pragma once
// Classical 2D inpainting (OpenCV's Telea and Navier-Stokes methods), used to make a reference
// image when the user has none from a learned 2D inpainter, and as a baseline in evaluation.
#include <string>

#include "io/image.h"

namespace ii {

enum class ClassicalInpainter { Telea, NavierStokes };
std::string inpainter_name(ClassicalInpainter method);            // "telea", "ns"
ClassicalInpainter parse_inpainter(const std::string& name);       // the names above, else an error

// Fills pixels where mask == 1. `radius` is the neighbourhood considered, in pixels.
Image inpaint_classical(const Image& rgb, const Image& mask, ClassicalInpainter method, double radius = 5.0);
inline Image inpaint_telea(const Image& rgb, const Image& mask, double radius = 5.0) {
  return inpaint_classical(rgb, mask, ClassicalInpainter::Telea, radius);
}

}  // namespace ii
