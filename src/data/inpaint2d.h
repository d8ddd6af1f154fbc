#pragma once
// Classical 2D inpainting (OpenCV's Telea and Navier-Stokes methods, CImg's patches), used to make
// a reference image when the user has none from a learned 2D inpainter, and as a baseline in
// evaluation.
#include <string>

#include "io/image.h"

namespace ii {

// Telea and NavierStokes diffuse the border's colours inward (smooth; a radial smear across a
// large hole); Patches copies patches of the picture inward (texture and edges continue; seams
// and repeats where it guesses wrong; slower: 0.8 s for a 35 k-pixel hole).
enum class ClassicalInpainter { Telea, NavierStokes, Patches };
std::string inpainter_name(ClassicalInpainter method);            // "telea", "ns", "patch"
ClassicalInpainter parse_inpainter(const std::string& name);       // the names above, else an error

// Fills pixels where mask == 1. `radius` is the neighbourhood considered, in pixels.
Image inpaint_classical(const Image& rgb, const Image& mask, ClassicalInpainter method, double radius = 5.0);
// The Patches method (inpaint_patch.cpp): CImg's exemplar-based inpainting.
Image inpaint_patches(const Image& rgb, const Image& mask);
inline Image inpaint_telea(const Image& rgb, const Image& mask, double radius = 5.0) {
  return inpaint_classical(rgb, mask, ClassicalInpainter::Telea, radius);
}

}  // namespace ii
