#pragma once
// Rendering a synthetic scene's views with exact removal ground truth, and degrading the
// object-free reference the way real 2D inpainters fail.
//
// Per view, three renders of the rasterizer (render/rasterizer.h):
//  * with_object: background + object (the "captured" image);
//  * clean: the background alone, i.e. exactly the scene with the object removed;
//  * object weight: background + object again, with colour 1 on the object's Gaussians, 0
//    on the others and a black background, so that the rendered value is W = Σ αᵢTᵢ over
//    the object's Gaussians in the with-object render (same α and T: colours do not change
//    them): how much of the pixel the object provides, occlusion by the background included.
//
// The visible-object mask is W >= kMaskWeightThreshold. Why this is where the two images
// differ: with colours and background in [0, 1], adding the object lowers every background
// Gaussian's weight (T only shrinks), and the weight the background loses is exactly what
// the object gains, plus at most the transmittance at which the rasterizer stops a pixel
// early (<= 1e-4 / (1 - kMaxOpacity) = 0.005, surfels.h). Hence per channel
//     |with_object - clean| <= W + 0.005,
// so outside the mask the two differ by less than kMaskWeightThreshold + 0.005 < 0.009
// (about two 8-bit levels), while inside it the object covers at least 1/255 of the pixel.
//
// Cost: each pass renders only the Gaussians that can reach the image (frustum culling with
// a 6-sigma + 4-pixel margin), and the two passes with the object only those that can reach
// the window around the object's splats; outside that window they equal the clean image and
// 0. Culling keeps the rows in order and drops only splats that draw nothing in the region,
// so every result is bit-identical to a render of the whole set (tested).
#include <cstdint>
#include <string>
#include <vector>

#include "io/image.h"
#include "synth/synth_scene.h"

namespace ii::synth {

inline constexpr float kMaskWeightThreshold = 1.0f / 255.0f;
// Bound on |with_object - clean| where the object's weight is W: W + kEarlyStopSlack.
inline constexpr float kEarlyStopSlack = 0.005f;

struct SynthViewImages {
  Image with_object;    // RGB as captured (empty when not asked for)
  Image clean;          // RGB of the background alone: the exact removal ground truth
  Image mask;           // 1 channel, exactly 0 or 1: object weight >= kMaskWeightThreshold
  Image object_weight;  // 1 channel, W in [0, 1]
  Image depth;          // expected camera z of the with-object render, 0 where nothing was hit
                        // (empty when with_object was not asked for)
  Image clean_depth;    // expected camera z of the background alone
};

class SynthRenderer {
 public:
  explicit SynthRenderer(const SynthScene& scene);
  // Renders one camera; with_object = false skips the captured image and its depth (test
  // views only need the clean image and the mask).
  SynthViewImages render(const Camera& camera, bool with_object = true) const;

 private:
  // Rows of the combined set (background first, then the object) that can touch pixels
  // [x0, x1) x [y0, y1), ascending; `camera_points` = the means in the camera's frame.
  std::vector<int64_t> visible_rows(const Camera& camera, const std::vector<float>& camera_points, int x0, int y0,
                                    int x1, int y1) const;
  GaussianSet rows(const std::vector<int64_t>& rows) const;

  const SynthScene& scene_;
  int64_t background_count_;
  torch::Tensor means_, quats_, scales_, opacities_, colors_;  // combined, float32, contiguous
  std::vector<float> reach_;                                   // per Gaussian: 6 x its largest scale
};

// RGB HxWx3 or HxWx1 tensor to an Image (float32, CPU).


enum class Degradation { none, blur, color, noise, telea, mixed };
// "none" | "blur" | "color" | "noise" | "telea" | "mixed"; throws Error naming `what`.
Degradation parse_degradation(const std::string& text, const std::string& what = "--degrade");
std::string to_string(Degradation mode);

// The object-free reference as a 2D inpainter might have made it: `clean` altered inside the
// object mask dilated by ~1.5% of the image size, feathered at its edge.
//   blur:  a blurred copy (the typical over-smooth fill)
//   color: a per-channel gain and offset with a soft brightness ramp (a colour cast)
//   noise: low-frequency noise (texture that does not match)
//   telea: OpenCV's Telea fill of the with-object image (a classical inpainter; `clean` unused)
//   mixed: one of the above, or blur + color, drawn from the seed
// Deterministic from the seed; `applied` receives the mode actually used (for mixed).
Image degrade_reference(const Image& clean, const Image& with_object, const Image& mask, Degradation mode,
                        uint64_t seed, std::string* applied = nullptr);

}  // namespace ii::synth
