#pragma once
// Classical 2D inpainting (OpenCV's Telea and Navier-Stokes methods, CImg's patches), used to make
// a reference image when the user has none from a learned 2D inpainter, and as a baseline in
// evaluation.
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "io/image.h"

namespace ii {

// Telea and NavierStokes diffuse the border's colours inward (smooth; a radial smear across a
// large hole); Patches copies patches of the picture inward (texture and edges continue; seams
// and repeats where it guesses wrong; slower: 0.8 s for a 35 k-pixel hole).
enum class ClassicalInpainter { Telea, NavierStokes, Patches };
std::string inpainter_name(ClassicalInpainter method);            // "telea", "ns", "patch"
ClassicalInpainter parse_inpainter(const std::string& name);       // the names above, else an error

// A learned 2D inpainter (inpaint/: LaMa), seen from here through what it paints.
class LearnedInpainter {
 public:
  virtual ~LearnedInpainter() = default;
  // `rgb` with the region (mask > 0.5) painted; the rest as it was.
  virtual Image paint(const Image& rgb, const Image& mask) const = 0;
  virtual std::string name() const = 0;             // "lama"
  virtual nlohmann::json describe() const = 0;      // for run.json: name, network, file, its SHA-256
};

// The 2D inpainter that paints a reference: a classical method, or a learned one when given.
struct Inpainter {
  // Navier-Stokes by default: as the reference on SPIn-NeRF scene 1 (object-free-photo protocol)
  // 15.01 dB in the region against Telea's 14.63, and equal or better on three synthetic rooms
  // (docs/benchmarks.md, "LaMa (the reference's inpainter)").
  ClassicalInpainter classical = ClassicalInpainter::NavierStokes;
  std::shared_ptr<const LearnedInpainter> learned;

  Inpainter(ClassicalInpainter method = ClassicalInpainter::NavierStokes) : classical(method) {}  // NOLINT: a method is one
  explicit Inpainter(std::shared_ptr<const LearnedInpainter> network) : learned(std::move(network)) {}
  std::string name() const { return learned ? learned->name() : inpainter_name(classical); }
  nlohmann::json describe() const;  // {"name": "telea"} or the learned one's
  Image paint(const Image& rgb, const Image& mask) const;
  bool operator==(ClassicalInpainter method) const { return !learned && classical == method; }
  bool operator!=(ClassicalInpainter method) const { return !(*this == method); }
};

// Fills pixels where mask == 1. `radius` is the neighbourhood considered, in pixels.
Image inpaint_classical(const Image& rgb, const Image& mask, ClassicalInpainter method, double radius = 5.0);
// The Patches method (inpaint_patch.cpp): CImg's exemplar-based inpainting.
Image inpaint_patches(const Image& rgb, const Image& mask);
inline Image inpaint_telea(const Image& rgb, const Image& mask, double radius = 5.0) {
  return inpaint_classical(rgb, mask, ClassicalInpainter::Telea, radius);
}

}  // namespace ii
