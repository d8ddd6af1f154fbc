// CUDA kernels of the rasterizer: the same math as the CPU back end (splat_math.h), with
// the usual GPU structure: one thread per Gaussian for projection, a radix sort of
// (tile, depth) keys, one 16x16 thread block per tile for compositing, and atomics to sum
// the per-Gaussian 2D gradients (so CUDA gradients are not bit-reproducible, unlike CPU).
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>
#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

#include "render/cuda/rasterizer_cuda.h"

namespace ii::render_detail::cuda {

using splat::PixelBox;
using splat::Splat2D;
using splat::Splat2DGrad;
using splat::ViewConsts;

namespace {

constexpr int kBlock = splat::kTileSize * splat::kTileSize;

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA rasterizer: ") + what + ": " + cudaGetErrorString(e));
}
#define II_CUDA_CHECK(expr) check((expr), #expr)

// What compositing needs about the image.
template <typename S>
struct ImageConsts {
  int width, height, tiles_x;
  S bg[3];
};

template <typename S>
ImageConsts<S> image_consts(const splat::CameraParams& cam) {
  return {cam.width, cam.height, cam.tiles_x(), {S(cam.background[0]), S(cam.background[1]), S(cam.background[2])}};
}

unsigned grid_for(int64_t n, int block) { return static_cast<unsigned>((n + block - 1) / block); }

template <typename S>
__global__ void project_kernel(ViewConsts<S> view, int64_t n, const S* means, const S* quats, const S* scales,
                               const S* opacities, const S* colors, int sh_degree, int num_coeffs,
                               Splat2D<S>* splats, PixelBox* boxes, int64_t* tiles_touched) {
  const int64_t i = blockIdx.x * int64_t(blockDim.x) + threadIdx.x;
  if (i >= n) return;
  const int64_t cstride = sh_degree < 0 ? 3 : int64_t(num_coeffs) * 3;
  Splat2D<S> s;
  PixelBox box;
  if (!splat::project_gaussian(view, means + i * 3, quats + i * 4, scales + i * 3, opacities[i], colors + i * cstride,
                               sh_degree, num_coeffs, s, box))
    box = PixelBox{};
  splats[i] = s;
  boxes[i] = box;
  int64_t count = 0;
  if (!box.empty()) {
    const splat::TileRect r = splat::tile_rect(box);
    count = int64_t(r.x1 - r.x0) * (r.y1 - r.y0);
  }
  tiles_touched[i] = count;
}

// Keys (tile << 32 | depth bits), values = Gaussian id, in Gaussian order; the stable
// radix sort then gives per tile front to back with ties by id, like the CPU.
template <typename S>
__global__ void emit_kernel(int64_t n, const Splat2D<S>* splats, const PixelBox* boxes, const int64_t* cum,
                            int tiles_x, uint64_t* keys, int32_t* values) {
  const int64_t i = blockIdx.x * int64_t(blockDim.x) + threadIdx.x;
  if (i >= n) return;
  const PixelBox box = boxes[i];
  if (box.empty()) return;
  int64_t pos = i == 0 ? 0 : cum[i - 1];
  const uint64_t depth_bits = __float_as_uint(static_cast<float>(splats[i].depth));  // z > 0: ordered bits
  const splat::TileRect r = splat::tile_rect(box);
  for (int ty = r.y0; ty < r.y1; ++ty)
    for (int tx = r.x0; tx < r.x1; ++tx) {
      keys[pos] = (uint64_t(ty * tiles_x + tx) << 32) | depth_bits;
      values[pos] = static_cast<int32_t>(i);
      ++pos;
    }
}

__global__ void tile_offsets_kernel(int64_t m, const uint64_t* keys, int tiles, int64_t* offsets) {
  const int64_t k = blockIdx.x * int64_t(blockDim.x) + threadIdx.x;
  if (k >= m) return;
  const int t = static_cast<int>(keys[k] >> 32);
  const int prev = k == 0 ? -1 : static_cast<int>(keys[k - 1] >> 32);
  for (int tt = prev + 1; tt <= t; ++tt) offsets[tt] = k;
  if (k == m - 1)
    for (int tt = t + 1; tt <= tiles; ++tt) offsets[tt] = m;
}

// Room for one batch of splats in shared memory, for either scalar type.
template <typename S>
struct alignas(16) Batch {
  Splat2D<S> splat[kBlock];
  int32_t id[kBlock];
};

template <typename S>
__global__ void __launch_bounds__(kBlock)
    raster_forward_kernel(ImageConsts<S> img, const int64_t* offsets, const int32_t* list, const Splat2D<S>* splats,
                          S* rgb, S* alpha, S* depth, S* final_T, int32_t* last_out) {
  __shared__ Batch<S> batch;
  const int tile = blockIdx.x;
  const int px = (tile % img.tiles_x) * splat::kTileSize + threadIdx.x % splat::kTileSize;
  const int py = (tile / img.tiles_x) * splat::kTileSize + threadIdx.x / splat::kTileSize;
  const bool inside = px < img.width && py < img.height;
  const int64_t start = offsets[tile], end = offsets[tile + 1];
  const S fx = S(px) + S(0.5), fy = S(py) + S(0.5);
  S T = 1, acc[3] = {0, 0, 0}, accd = 0;
  int32_t last = -1;
  bool done = !inside;
  for (int64_t b0 = start; b0 < end; b0 += kBlock) {
    if (__syncthreads_count(done) == kBlock) break;
    const int64_t k = b0 + threadIdx.x;
    if (k < end) batch.splat[threadIdx.x] = splats[list[k]];
    __syncthreads();
    const int count = static_cast<int>(end - b0 < kBlock ? end - b0 : kBlock);
    for (int j = 0; j < count && !done; ++j) {
      S dx, dy, vis, raw;
      const S a = splat::splat_alpha(batch.splat[j], fx, fy, dx, dy, vis, raw);
      if (a == S(0)) continue;
      const S next_T = T * (S(1) - a);
      if (next_T <= S(splat::kTransmittanceMin)) {
        done = true;
        break;
      }
      const S w = a * T;
      const Splat2D<S>& s = batch.splat[j];
      acc[0] += s.rgb[0] * w;
      acc[1] += s.rgb[1] * w;
      acc[2] += s.rgb[2] * w;
      accd += s.depth * w;
      T = next_T;
      last = static_cast<int32_t>(b0 + j - start);
    }
  }
  if (!inside) return;
  const int64_t o = int64_t(py) * img.width + px;
  for (int c = 0; c < 3; ++c) rgb[o * 3 + c] = acc[c] + T * img.bg[c];
  const S a = S(1) - T;
  alpha[o] = a;
  depth[o] = accd / (a > S(1e-10) ? a : S(1e-10));
  final_T[o] = T;
  last_out[o] = last;
}

template <typename S>
__device__ __forceinline__ S warp_sum(S v) {
  for (int offset = 16; offset > 0; offset /= 2) v += __shfl_down_sync(0xffffffffu, v, offset);
  return v;
}

template <typename S>
__global__ void __launch_bounds__(kBlock)
    raster_backward_kernel(ImageConsts<S> img, const int64_t* offsets, const int32_t* list,
                           const Splat2D<S>* splats, const int32_t* last_in, const S* final_T, const S* alpha_out,
                           const S* depth_out, const S* g_rgb, const S* g_alpha, const S* g_depth,
                           Splat2DGrad<S>* v2d) {
  __shared__ Batch<S> batch;
  __shared__ int kmax;
  const int tile = blockIdx.x;
  const int px = (tile % img.tiles_x) * splat::kTileSize + threadIdx.x % splat::kTileSize;
  const int py = (tile / img.tiles_x) * splat::kTileSize + threadIdx.x / splat::kTileSize;
  const bool inside = px < img.width && py < img.height;
  const int64_t start = offsets[tile];
  const int64_t o = inside ? int64_t(py) * img.width + px : 0;
  const S fx = S(px) + S(0.5), fy = S(py) + S(0.5);

  const int32_t last = inside ? last_in[o] : -1;
  S T = inside ? final_T[o] : S(1);
  const S T_end = T;
  S Sc[3], gC[3], Sd = 0, gD = 0, gA = 0;
  for (int c = 0; c < 3; ++c) {
    Sc[c] = T_end * img.bg[c];
    gC[c] = inside ? g_rgb[o * 3 + c] : S(0);
  }
  if (inside) {
    const S a = alpha_out[o], gd = g_depth[o];
    gD = gd / (a > S(1e-10) ? a : S(1e-10));
    gA = g_alpha[o] - (a > S(1e-10) ? gd * depth_out[o] / a : S(0));
  }
  if (threadIdx.x == 0) kmax = -1;
  __syncthreads();
  atomicMax(&kmax, last);
  __syncthreads();
  const int64_t stop = start + kmax + 1;

  const int lane = threadIdx.x % 32;
  for (int64_t b1 = stop; b1 > start; b1 -= kBlock) {
    const int64_t b0 = b1 - kBlock > start ? b1 - kBlock : start;
    __syncthreads();
    const int64_t k = b1 - 1 - threadIdx.x;  // back to front
    if (k >= b0) {
      const int32_t g = list[k];
      batch.id[threadIdx.x] = g;
      batch.splat[threadIdx.x] = splats[g];
    }
    __syncthreads();
    const int count = static_cast<int>(b1 - b0);
    for (int j = 0; j < count; ++j) {
      const int64_t rel = b1 - 1 - j - start;
      const Splat2D<S>& s = batch.splat[j];
      Splat2DGrad<S> gr{};
      bool valid = false;
      if (rel <= last) {
        S dx, dy, vis, raw;
        const S a = splat::splat_alpha(s, fx, fy, dx, dy, vis, raw);
        if (a != S(0)) {
          valid = true;
          const S ra = S(1) / (S(1) - a);
          const S Ti = T * ra;
          const S w = a * Ti;
          S v_alpha = gA * T_end * ra;
          for (int c = 0; c < 3; ++c) {
            gr.rgb[c] = gC[c] * w;
            v_alpha += gC[c] * (s.rgb[c] * Ti - Sc[c] * ra);
            Sc[c] += s.rgb[c] * w;
          }
          gr.depth = gD * w;
          v_alpha += gD * (s.depth * Ti - Sd * ra);
          Sd += s.depth * w;
          T = Ti;
          if (raw <= S(splat::kAlphaMax)) {
            gr.opacity = v_alpha * vis;
            const S v_sigma = -v_alpha * a;
            gr.A = v_sigma * S(0.5) * dx * dx;
            gr.B = v_sigma * dx * dy;
            gr.C = v_sigma * S(0.5) * dy * dy;
            gr.mx = v_sigma * (s.A * dx + s.B * dy);
            gr.my = v_sigma * (s.B * dx + s.C * dy);
          }
        }
      }
      // Sum over the warp first: one set of atomics per warp and splat.
      if (!__any_sync(0xffffffffu, valid)) continue;
      S* f = reinterpret_cast<S*>(&gr);
      for (int c = 0; c < splat::kGradScalars; ++c) f[c] = warp_sum(f[c]);
      if (lane == 0) {
        S* dst = reinterpret_cast<S*>(&v2d[batch.id[j]]);
        for (int c = 0; c < splat::kGradScalars; ++c) atomicAdd(dst + c, f[c]);
      }
    }
  }
}

template <typename S>
__global__ void vjp_kernel(ViewConsts<S> view, int64_t n, const S* means, const S* quats, const S* scales,
                           const S* colors, int sh_degree, int num_coeffs, const PixelBox* boxes,
                           const Splat2DGrad<S>* v2d, S* v_means, S* v_quats, S* v_scales, S* v_opacities,
                           S* v_colors) {
  const int64_t i = blockIdx.x * int64_t(blockDim.x) + threadIdx.x;
  if (i >= n || boxes[i].empty()) return;
  const int64_t cstride = sh_degree < 0 ? 3 : int64_t(num_coeffs) * 3;
  splat::project_gaussian_vjp(view, means + i * 3, quats + i * 4, scales + i * 3, colors + i * cstride, sh_degree,
                              v2d[i], v_means + i * 3, v_quats + i * 4, v_scales + i * 3, v_opacities + i,
                              v_colors + i * cstride);
}

template <typename S>
int64_t forward_impl(const splat::CameraParams& cam, const SplatInputs& in, const ForwardBuffers& b) {
  const ViewConsts<S> view = splat::view_consts<S>(cam);
  const int64_t n = in.count;
  const int tiles = cam.tiles_x() * cam.tiles_y();
  auto* splats = static_cast<Splat2D<S>*>(b.splats);
  auto* boxes = reinterpret_cast<PixelBox*>(b.boxes);

  int64_t m = 0;
  int64_t* cum = nullptr;
  if (n > 0) {
    auto* touched = static_cast<int64_t*>(b.scratch(n * sizeof(int64_t)));
    cum = static_cast<int64_t*>(b.scratch(n * sizeof(int64_t)));
    project_kernel<S><<<grid_for(n, 256), 256>>>(
        view, n, static_cast<const S*>(in.means), static_cast<const S*>(in.quats), static_cast<const S*>(in.scales),
        static_cast<const S*>(in.opacities), static_cast<const S*>(in.colors), in.sh_degree, in.num_coeffs, splats,
        boxes, touched);
    II_CUDA_CHECK(cudaGetLastError());
    size_t temp_bytes = 0;
    II_CUDA_CHECK(cub::DeviceScan::InclusiveSum(nullptr, temp_bytes, touched, cum, n));
    void* temp = b.scratch(temp_bytes);
    II_CUDA_CHECK(cub::DeviceScan::InclusiveSum(temp, temp_bytes, touched, cum, n));
    II_CUDA_CHECK(cudaMemcpy(&m, cum + n - 1, sizeof(int64_t), cudaMemcpyDeviceToHost));
  }
  int32_t* list = b.alloc_tile_gaussians(m);
  if (m > 0) {
    auto* keys_in = static_cast<uint64_t*>(b.scratch(m * sizeof(uint64_t)));
    auto* keys_out = static_cast<uint64_t*>(b.scratch(m * sizeof(uint64_t)));
    auto* values_in = static_cast<int32_t*>(b.scratch(m * sizeof(int32_t)));
    emit_kernel<S><<<grid_for(n, 256), 256>>>(n, splats, boxes, cum, cam.tiles_x(), keys_in, values_in);
    II_CUDA_CHECK(cudaGetLastError());
    int tile_bits = 1;
    while ((int64_t(1) << tile_bits) < tiles) ++tile_bits;
    size_t temp_bytes = 0;
    II_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, temp_bytes, keys_in, keys_out, values_in, list, m, 0,
                                                  32 + tile_bits));
    void* temp = b.scratch(temp_bytes);
    II_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(temp, temp_bytes, keys_in, keys_out, values_in, list, m, 0,
                                                  32 + tile_bits));
    tile_offsets_kernel<<<grid_for(m, 256), 256>>>(m, keys_out, tiles, b.tile_offsets);
    II_CUDA_CHECK(cudaGetLastError());
  } else {
    II_CUDA_CHECK(cudaMemset(b.tile_offsets, 0, (tiles + 1) * sizeof(int64_t)));
  }
  raster_forward_kernel<S><<<tiles, kBlock>>>(image_consts<S>(cam), b.tile_offsets, list, splats,
                                               static_cast<S*>(b.rgb), static_cast<S*>(b.alpha),
                                               static_cast<S*>(b.depth), static_cast<S*>(b.final_T), b.last);
  II_CUDA_CHECK(cudaGetLastError());
  return m;
}

template <typename S>
void backward_impl(const splat::CameraParams& cam, const SplatInputs& in, const BackwardBuffers& b) {
  const int64_t n = in.count;
  if (n == 0) return;
  const int tiles = cam.tiles_x() * cam.tiles_y();
  auto* v2d = static_cast<Splat2DGrad<S>*>(b.scratch(n * sizeof(Splat2DGrad<S>)));
  II_CUDA_CHECK(cudaMemset(v2d, 0, n * sizeof(Splat2DGrad<S>)));
  if (b.num_entries > 0) {
    raster_backward_kernel<S><<<tiles, kBlock>>>(
        image_consts<S>(cam), b.tile_offsets, b.tile_gaussians, static_cast<const Splat2D<S>*>(b.splats), b.last,
        static_cast<const S*>(b.final_T), static_cast<const S*>(b.alpha), static_cast<const S*>(b.depth),
        static_cast<const S*>(b.grad_rgb), static_cast<const S*>(b.grad_alpha), static_cast<const S*>(b.grad_depth),
        v2d);
    II_CUDA_CHECK(cudaGetLastError());
  }
  vjp_kernel<S><<<grid_for(n, 256), 256>>>(
      splat::view_consts<S>(cam), n, static_cast<const S*>(in.means), static_cast<const S*>(in.quats),
      static_cast<const S*>(in.scales), static_cast<const S*>(in.colors), in.sh_degree, in.num_coeffs,
      reinterpret_cast<const PixelBox*>(b.boxes), v2d, static_cast<S*>(b.v_means), static_cast<S*>(b.v_quats),
      static_cast<S*>(b.v_scales), static_cast<S*>(b.v_opacities), static_cast<S*>(b.v_colors));
  II_CUDA_CHECK(cudaGetLastError());
  // The scratch memory is released when the caller returns: finish using it first.
  II_CUDA_CHECK(cudaDeviceSynchronize());
}

// Makes `device` current for one call and restores the previous one.
class DeviceGuard {
 public:
  explicit DeviceGuard(int device) {
    II_CUDA_CHECK(cudaGetDevice(&previous_));
    if (device != previous_) II_CUDA_CHECK(cudaSetDevice(device));
  }
  ~DeviceGuard() { cudaSetDevice(previous_); }
  DeviceGuard(const DeviceGuard&) = delete;
  DeviceGuard& operator=(const DeviceGuard&) = delete;

 private:
  int previous_ = 0;
};

}  // namespace

int64_t forward(const splat::CameraParams& cam, const SplatInputs& in, const ForwardBuffers& buffers) {
  const DeviceGuard guard(in.device);
  const int64_t m = in.is_double ? forward_impl<double>(cam, in, buffers) : forward_impl<float>(cam, in, buffers);
  // Scratch memory goes back to the caller's allocator on return.
  II_CUDA_CHECK(cudaDeviceSynchronize());
  return m;
}

void backward(const splat::CameraParams& cam, const SplatInputs& in, const BackwardBuffers& buffers) {
  const DeviceGuard guard(in.device);
  if (in.is_double)
    backward_impl<double>(cam, in, buffers);
  else
    backward_impl<float>(cam, in, buffers);
}

}  // namespace ii::render_detail::cuda
