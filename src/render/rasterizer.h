#pragma once
// Differentiable 3D Gaussian splatting with gsplat's "classic" pinhole semantics (the
// renderer the official model was trained and evaluated with, spec §4.3):
//
//  * covariance Σ = R S Sᵀ Rᵀ from the normalised quaternion (w, x, y, z) and the scales;
//  * world to camera with Camera::w2c_opencv() (x right, y down, z forward); pinhole
//    fx, fy, cx, cy in pixels, pixel centres at integer + 0.5;
//  * EWA projection with the perspective Jacobian (x/z, y/z clamped to 1.3× the image's
//    extent when forming the Jacobian), plus eps2d·I (0.3 by default);
//  * Gaussians with camera z outside [near, far] are culled; each covers the 16×16 tiles
//    of its 3-sigma radius (larger eigenvalue of the 2D covariance, rounded up);
//  * per tile, front-to-back by camera z: αᵢ = min(0.999, oᵢ exp(−½ Δᵀ Σ₂D⁻¹ Δ)),
//    α < 1/255 skipped, a pixel stops before the splat that would bring its transmittance
//    to ≤ 1e-4; colour = Σ cᵢ αᵢ Tᵢ + T·background, alpha = 1 − T, expected depth =
//    Σ zᵢ αᵢ Tᵢ / max(alpha, 1e-10).
//  * colours are RGB, or spherical harmonics evaluated in the direction mean − camera
//    centre, + 0.5, clamped at 0 from below.
//
// render() runs on the CPU (at::get_num_threads() threads over Gaussians and tiles;
// bit-identical output and gradients for any thread count) or, when built with the CUDA kernels and given CUDA tensors, on the GPU.
// It is differentiable with respect to means, quats, scales, opacities and colours (an
// analytic backward; nothing is differentiable with respect to the camera).
//
// Degenerate input never throws or crashes; it renders what is left:
//  * a Gaussian with any NaN or infinite parameter (including its colours) is skipped and
//    gets zero gradient;
//  * Gaussians behind the camera, nearer than near or farther than far are culled;
//  * zero scales give a splat of the eps2d blur only; scales so large that the 2D
//    covariance overflows skip the Gaussian; a zero quaternion is the identity rotation;
//  * opacities below 1/255 can never contribute and are skipped;
//  * an empty set renders the background (alpha 0, depth 0); 1×1 images work.
// Shapes and dtypes that do not fit are errors (ii::Error) naming the tensor.
#include <array>
#include <optional>
#include <string>

#include "common/torch.h"

#include "camera/camera.h"
#include "gaussians/gaussians.h"

namespace ii {

struct RenderCamera {
  Camera camera;  // intrinsics (width, height, fx, fy, cx, cy) + OpenGL camera-to-world
  float near_plane = 0.01f;
  float far_plane = 1000.f;
};

struct RenderOptions {
  std::array<float, 3> background{1.f, 1.f, 1.f};
  float eps2d = 0.3f;
};

struct RenderOutput {
  torch::Tensor rgb;    // (H, W, 3)
  torch::Tensor alpha;  // (H, W, 1) accumulated opacity 1 - T
  torch::Tensor depth;  // (H, W, 1) expected camera z (0 where nothing was hit)
};

// The fast renderer (CPU tiles, or CUDA). Output dtype and device follow `means`.
RenderOutput render(const GaussianSet& gaussians, const RenderCamera& camera, const RenderOptions& options = {});

// A direct implementation of the same semantics for tests and as a benchmark baseline:
// plain LibTorch operations, all pixels at once, one Gaussian after another in depth order
// (differentiable through LibTorch's own autograd). Cost O(N × H × W); small scenes only.
RenderOutput render_reference(const GaussianSet& gaussians, const RenderCamera& camera,
                              const RenderOptions& options = {});

// Whether render() can run on CUDA tensors in this build.
bool render_has_cuda();
// Where render() runs for work meant for `device`: there when it is the CPU or when this build
// renders on CUDA, else the CPU.
torch::Device render_device(const torch::Device& device);

}  // namespace ii
