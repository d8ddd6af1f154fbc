#pragma once
// Per-Gaussian and per-pixel math of the rasterizer, shared by the CPU and CUDA back ends
// so that both compute the same thing: projection of one 3D Gaussian to a 2D splat (and its
// vector-Jacobian product), spherical harmonics, and the per-pixel alpha. Plain structs and
// templates on the scalar type (float, or double for finite-difference tests); no LibTorch.
//
// Semantics are those of gsplat's "classic" pinhole rasterization (see rasterizer.h).
#include <cstdint>

#include <cmath>

#if defined(__CUDACC__)
#define II_HD __host__ __device__ __forceinline__
#else
#define II_HD inline
#endif

namespace ii::splat {

constexpr int kTileSize = 16;
constexpr double kAlphaMin = 1.0 / 255.0;    // weaker contributions are skipped
constexpr double kAlphaMax = 0.999;          // alpha is clamped here (no gradient above)
constexpr double kTransmittanceMin = 1e-4;   // a pixel stops before T would reach this
constexpr double kSigmaExtent = 3.0;         // tile footprint radius in standard deviations
constexpr double kFovClampFactor = 1.3;      // x/z, y/z clamp for the Jacobian, x FOV extent
constexpr double kQuatNormMin = 1e-12;       // |q| below this: identity rotation

// Everything the per-Gaussian math needs about the view. Doubles so that one struct
// serves both scalar types; kernels convert once.
struct CameraParams {
  double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};  // world-to-camera rotation, OpenCV axes, row-major
  double t[3] = {0, 0, 0};                    // world-to-camera translation
  double campos[3] = {0, 0, 0};               // camera centre in world coordinates
  double fx = 1, fy = 1, cx = 0, cy = 0;      // pixels; principal point continuous
  int width = 1, height = 1;
  double near_plane = 0.01, far_plane = 1000.0;
  double eps2d = 0.3;
  double background[3] = {1, 1, 1};

  II_HD int tiles_x() const { return (width + kTileSize - 1) / kTileSize; }
  II_HD int tiles_y() const { return (height + kTileSize - 1) / kTileSize; }
};

// ---- scalar helpers (overloads pick the float or double device/host function) ------------
II_HD float s_sqrt(float x) { return ::sqrtf(x); }
II_HD double s_sqrt(double x) { return ::sqrt(x); }
II_HD float s_exp(float x) { return ::expf(x); }
II_HD double s_exp(double x) { return ::exp(x); }
II_HD float s_log(float x) { return ::logf(x); }
II_HD double s_log(double x) { return ::log(x); }
II_HD float s_floor(float x) { return ::floorf(x); }
II_HD double s_floor(double x) { return ::floor(x); }
II_HD float s_ceil(float x) { return ::ceilf(x); }
II_HD double s_ceil(double x) { return ::ceil(x); }
// NaN and +-inf fail x - x == 0; written out because isfinite differs between host and device.
template <typename S>
II_HD bool s_finite(S x) {
  return (x - x) == S(0);
}
template <typename S>
II_HD S s_min(S a, S b) {
  return a < b ? a : b;
}
template <typename S>
II_HD S s_max(S a, S b) {
  return a > b ? a : b;
}
II_HD int clamp_int(double v, int lo, int hi) {
  // Comparisons first: casting an out-of-range double to int is undefined.
  if (!(v > lo)) return lo;
  if (!(v < hi)) return hi;
  return static_cast<int>(v);
}

// ---- small fixed-size matrices (row-major) -----------------------------------------------
template <typename S>
struct M3 {
  S m[3][3];
};
template <typename S>
struct V3 {
  S x, y, z;
};

template <typename S>
II_HD M3<S> mul(const M3<S>& a, const M3<S>& b) {
  M3<S> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
  return r;
}
template <typename S>
II_HD M3<S> mul_bt(const M3<S>& a, const M3<S>& b) {  // a * b^T
  M3<S> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[i][0] * b.m[j][0] + a.m[i][1] * b.m[j][1] + a.m[i][2] * b.m[j][2];
  return r;
}
template <typename S>
II_HD M3<S> mul_at(const M3<S>& a, const M3<S>& b) {  // a^T * b
  M3<S> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.m[i][j] = a.m[0][i] * b.m[0][j] + a.m[1][i] * b.m[1][j] + a.m[2][i] * b.m[2][j];
  return r;
}

template <typename S>
II_HD M3<S> camera_rotation(const CameraParams& cam) {
  M3<S> w;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) w.m[i][j] = static_cast<S>(cam.R[i * 3 + j]);
  return w;
}

// CameraParams converted once per render to the scalar type, with the derived constants
// (the Jacobian's clamp limits), so the per-Gaussian code does no divisions for them.
template <typename S>
struct ViewConsts {
  M3<S> W;
  S t[3], campos[3];
  S fx, fy, cx, cy;
  S lim_xp, lim_xn, lim_yp, lim_yn;  // x/z in [-lim_xn, lim_xp], y/z likewise
  S eps2d, near_plane, far_plane;
  S width, height;
  int width_px, height_px, tiles_x, tiles_y;
};

template <typename S>
ViewConsts<S> view_consts(const CameraParams& cam) {
  ViewConsts<S> v;
  v.W = camera_rotation<S>(cam);
  for (int i = 0; i < 3; ++i) {
    v.t[i] = S(cam.t[i]);
    v.campos[i] = S(cam.campos[i]);
  }
  v.fx = S(cam.fx);
  v.fy = S(cam.fy);
  v.cx = S(cam.cx);
  v.cy = S(cam.cy);
  // gsplat: limits = principal-point distance to the border / f + 0.3 tan(fov/2).
  const S tan_x = S(0.5 * cam.width / cam.fx), tan_y = S(0.5 * cam.height / cam.fy);
  const S extra = S(kFovClampFactor - 1.0);
  v.lim_xp = S((cam.width - cam.cx) / cam.fx) + extra * tan_x;
  v.lim_xn = S(cam.cx / cam.fx) + extra * tan_x;
  v.lim_yp = S((cam.height - cam.cy) / cam.fy) + extra * tan_y;
  v.lim_yn = S(cam.cy / cam.fy) + extra * tan_y;
  v.eps2d = S(cam.eps2d);
  v.near_plane = S(cam.near_plane);
  v.far_plane = S(cam.far_plane);
  v.width = S(cam.width);
  v.height = S(cam.height);
  v.width_px = cam.width;
  v.height_px = cam.height;
  v.tiles_x = cam.tiles_x();
  v.tiles_y = cam.tiles_y();
  return v;
}

// Rotation of the unit quaternion (w, x, y, z).
template <typename S>
II_HD M3<S> quat_to_rotation(S w, S x, S y, S z) {
  M3<S> r;
  r.m[0][0] = 1 - 2 * (y * y + z * z);
  r.m[0][1] = 2 * (x * y - w * z);
  r.m[0][2] = 2 * (x * z + w * y);
  r.m[1][0] = 2 * (x * y + w * z);
  r.m[1][1] = 1 - 2 * (x * x + z * z);
  r.m[1][2] = 2 * (y * z - w * x);
  r.m[2][0] = 2 * (x * z - w * y);
  r.m[2][1] = 2 * (y * z + w * x);
  r.m[2][2] = 1 - 2 * (x * x + y * y);
  return r;
}

// d(loss)/d(w,x,y,z) of the unit quaternion from d(loss)/dR (written out from the formula
// above: each entry of R is a quadratic in the four components).
template <typename S>
II_HD void quat_to_rotation_vjp(S w, S x, S y, S z, const M3<S>& g, S out[4]) {
  const auto& G = g.m;
  out[0] = 2 * (-z * G[0][1] + y * G[0][2] + z * G[1][0] - x * G[1][2] - y * G[2][0] + x * G[2][1]);
  out[1] = 2 * (y * G[0][1] + z * G[0][2] + y * G[1][0] - 2 * x * G[1][1] - w * G[1][2] + z * G[2][0] +
                w * G[2][1] - 2 * x * G[2][2]);
  out[2] = 2 * (-2 * y * G[0][0] + x * G[0][1] + w * G[0][2] + x * G[1][0] + z * G[1][2] - w * G[2][0] +
                z * G[2][1] - 2 * y * G[2][2]);
  out[3] = 2 * (-2 * z * G[0][0] - w * G[0][1] + x * G[0][2] + w * G[1][0] - 2 * z * G[1][1] + y * G[1][2] +
                x * G[2][0] + y * G[2][1]);
}

// ---- spherical harmonics ------------------------------------------------------------------
// Value and gradient with respect to (x, y, z): enough arithmetic for sh_basis below, which
// then gives the basis and its gradient in one evaluation.
template <typename S>
struct Dual3 {
  S v, dx, dy, dz;
};
template <typename S>
II_HD Dual3<S> operator+(const Dual3<S>& a, const Dual3<S>& b) {
  return {a.v + b.v, a.dx + b.dx, a.dy + b.dy, a.dz + b.dz};
}
template <typename S>
II_HD Dual3<S> operator-(const Dual3<S>& a, const Dual3<S>& b) {
  return {a.v - b.v, a.dx - b.dx, a.dy - b.dy, a.dz - b.dz};
}
template <typename S>
II_HD Dual3<S> operator*(const Dual3<S>& a, const Dual3<S>& b) {
  return {a.v * b.v, a.dx * b.v + a.v * b.dx, a.dy * b.v + a.v * b.dy, a.dz * b.v + a.v * b.dz};
}
template <typename S>
II_HD Dual3<S> operator*(S k, const Dual3<S>& a) {
  return {k * a.v, k * a.dx, k * a.dy, k * a.dz};
}

template <typename T>
struct ScalarOf {
  using type = T;
};
template <typename S>
struct ScalarOf<Dual3<S>> {
  using type = S;
};

template <typename S>
II_HD S make_constant(S c, S*) {
  return c;
}
template <typename S>
II_HD Dual3<S> make_constant(S c, Dual3<S>*) {
  return {c, S(0), S(0), S(0)};
}

// Real SH basis up to degree 3 with the usual graphics constants. The polynomials are
// written in x, y, z without using x²+y²+z² = 1; the normalisation of the direction is
// differentiated separately.
template <typename T>
II_HD void sh_basis(int degree, T x, T y, T z, T* b) {
  using S = typename ScalarOf<T>::type;
  b[0] = make_constant(S(0.28209479177387814), static_cast<T*>(nullptr));
  if (degree < 1) return;
  b[1] = S(-0.4886025119029199) * y;
  b[2] = S(0.4886025119029199) * z;
  b[3] = S(-0.4886025119029199) * x;
  if (degree < 2) return;
  const T xx = x * x, yy = y * y, zz = z * z, xy = x * y, yz = y * z, xz = x * z;
  b[4] = S(1.0925484305920792) * xy;
  b[5] = S(-1.0925484305920792) * yz;
  b[6] = S(0.31539156525252005) * (S(2) * zz - xx - yy);
  b[7] = S(-1.0925484305920792) * xz;
  b[8] = S(0.5462742152960396) * (xx - yy);
  if (degree < 3) return;
  b[9] = S(-0.5900435899266435) * y * (S(3) * xx - yy);
  b[10] = S(2.890611442640554) * xy * z;
  b[11] = S(-0.4570457994644658) * y * (S(4) * zz - xx - yy);
  b[12] = S(0.3731763325901154) * z * (S(2) * zz - S(3) * xx - S(3) * yy);
  b[13] = S(-0.4570457994644658) * x * (S(4) * zz - xx - yy);
  b[14] = S(1.445305721320277) * z * (xx - yy);
  b[15] = S(-0.5900435899266435) * x * (xx - S(3) * yy);
}

II_HD constexpr int sh_coeff_count(int degree) { return (degree + 1) * (degree + 1); }

// Colour of one Gaussian from its SH coefficients `coeffs` (K x 3, coefficient-major) in the
// direction `dir` (mean - camera centre, not normalised): max(sum + 0.5, 0) per channel.
template <typename S>
II_HD void sh_to_color(int degree, const S* coeffs, S dx, S dy, S dz, S rgb[3]) {
  const S n = s_sqrt(dx * dx + dy * dy + dz * dz);
  const S inv = n > S(0) ? S(1) / n : S(0);
  S b[16];
  sh_basis<S>(degree, dx * inv, dy * inv, dz * inv, b);
  const int k = sh_coeff_count(degree);
  for (int c = 0; c < 3; ++c) {
    S sum = 0;
    for (int i = 0; i < k; ++i) sum += b[i] * coeffs[i * 3 + c];
    rgb[c] = s_max(sum + S(0.5), S(0));
  }
}

// VJP of sh_to_color: adds into v_coeffs (K x 3) and v_dir (3).
template <typename S>
II_HD void sh_to_color_vjp(int degree, const S* coeffs, S dx, S dy, S dz, const S v_rgb[3], S* v_coeffs,
                           S v_dir[3]) {
  const S n = s_sqrt(dx * dx + dy * dy + dz * dz);
  const S inv = n > S(0) ? S(1) / n : S(0);
  const S ux = dx * inv, uy = dy * inv, uz = dz * inv;
  Dual3<S> b[16];
  sh_basis<Dual3<S>>(degree, Dual3<S>{ux, 1, 0, 0}, Dual3<S>{uy, 0, 1, 0}, Dual3<S>{uz, 0, 0, 1}, b);
  const int k = sh_coeff_count(degree);
  S vu[3] = {0, 0, 0};
  for (int c = 0; c < 3; ++c) {
    S sum = 0;
    for (int i = 0; i < k; ++i) sum += b[i].v * coeffs[i * 3 + c];
    if (sum + S(0.5) < S(0)) continue;  // clamped: no gradient
    const S g = v_rgb[c];
    for (int i = 0; i < k; ++i) {
      v_coeffs[i * 3 + c] += g * b[i].v;
      vu[0] += g * coeffs[i * 3 + c] * b[i].dx;
      vu[1] += g * coeffs[i * 3 + c] * b[i].dy;
      vu[2] += g * coeffs[i * 3 + c] * b[i].dz;
    }
  }
  // u = d/|d|: du/dd = (I - u u^T)/|d|.
  const S dot = vu[0] * ux + vu[1] * uy + vu[2] * uz;
  v_dir[0] += (vu[0] - dot * ux) * inv;
  v_dir[1] += (vu[1] - dot * uy) * inv;
  v_dir[2] += (vu[2] - dot * uz) * inv;
}

// ---- projection ----------------------------------------------------------------------------
// A projected splat: what compositing reads per Gaussian.
template <typename S>
struct Splat2D {
  S mx, my;     // pixel-space mean
  S A, B, C;    // conic = inverse 2D covariance [[A, B], [B, C]]
  S depth;      // camera-space z
  S opacity;
  S level;      // ln(255 opacity): alpha >= 1/255 exactly where sigma <= level
  S rgb[3];
};
constexpr int kSplatScalars = 11;  // Splat2D as a row of scalars
constexpr int kGradScalars = 10;   // Splat2DGrad likewise

// Pixel rectangle [x0, x1) x [y0, y1) in which the splat can reach alpha >= 1/255 and which
// gsplat's tile footprint covers; empty (x0 >= x1) when the Gaussian is culled.
struct PixelBox {
  int32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  II_HD bool empty() const { return x0 >= x1 || y0 >= y1; }
};

// The 16x16 tiles [x0, x1) x [y0, y1) that a pixel box touches.
struct TileRect {
  int x0, y0, x1, y1;
};
II_HD TileRect tile_rect(const PixelBox& b) {
  return {b.x0 / kTileSize, b.y0 / kTileSize, (b.x1 + kTileSize - 1) / kTileSize, (b.y1 + kTileSize - 1) / kTileSize};
}

// Camera-space geometry of one Gaussian, recomputed by the backward pass.
template <typename S>
struct Projection {
  V3<S> p;          // camera-space mean
  M3<S> rot;        // rotation of the normalised quaternion
  S qn[4];          // normalised quaternion
  S qnorm;          // |q| (clamped)
  M3<S> cov_cam;    // camera-space 3D covariance
  S J[2][3];        // perspective Jacobian (with the FOV clamp)
  bool clamp_x, clamp_y;  // whether x/z, y/z were clamped
  S cov2d[3];       // a, b, c of the 2D covariance including eps2d
};

template <typename S>
II_HD void project_geometry(const ViewConsts<S>& cam, const S* mean, const S* quat, const S* scale,
                            Projection<S>& pr) {
  const M3<S>& W = cam.W;
  pr.p.x = W.m[0][0] * mean[0] + W.m[0][1] * mean[1] + W.m[0][2] * mean[2] + cam.t[0];
  pr.p.y = W.m[1][0] * mean[0] + W.m[1][1] * mean[1] + W.m[1][2] * mean[2] + cam.t[1];
  pr.p.z = W.m[2][0] * mean[0] + W.m[2][1] * mean[1] + W.m[2][2] * mean[2] + cam.t[2];

  const S n = s_sqrt(quat[0] * quat[0] + quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3]);
  pr.qnorm = s_max(n, S(kQuatNormMin));
  const S inv_n = S(1) / pr.qnorm;
  for (int i = 0; i < 4; ++i) pr.qn[i] = quat[i] * inv_n;
  pr.rot = quat_to_rotation(pr.qn[0], pr.qn[1], pr.qn[2], pr.qn[3]);

  // Sigma = R S S^T R^T = M M^T with M = R diag(s); camera frame: W Sigma W^T.
  M3<S> M;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) M.m[i][j] = pr.rot.m[i][j] * scale[j];
  const M3<S> cov = mul_bt(M, M);
  pr.cov_cam = mul_bt(mul(W, cov), W);

  const S x = pr.p.x, y = pr.p.y, z = pr.p.z;
  const S lim_xp = cam.lim_xp, lim_xn = cam.lim_xn, lim_yp = cam.lim_yp, lim_yn = cam.lim_yn;
  const S rz = S(1) / z;
  const S u = x * rz, v = y * rz;
  pr.clamp_x = !(u <= lim_xp && u >= -lim_xn);
  pr.clamp_y = !(v <= lim_yp && v >= -lim_yn);
  const S uc = s_min(lim_xp, s_max(-lim_xn, u));
  const S vc = s_min(lim_yp, s_max(-lim_yn, v));
  const S fx = cam.fx, fy = cam.fy;
  pr.J[0][0] = fx * rz;
  pr.J[0][1] = 0;
  pr.J[0][2] = -fx * uc * rz;
  pr.J[1][0] = 0;
  pr.J[1][1] = fy * rz;
  pr.J[1][2] = -fy * vc * rz;

  // cov2d = J cov_cam J^T + eps2d I
  S JC[2][3];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      JC[i][j] = pr.J[i][0] * pr.cov_cam.m[0][j] + pr.J[i][1] * pr.cov_cam.m[1][j] + pr.J[i][2] * pr.cov_cam.m[2][j];
  const S eps = cam.eps2d;
  pr.cov2d[0] = JC[0][0] * pr.J[0][0] + JC[0][1] * pr.J[0][1] + JC[0][2] * pr.J[0][2] + eps;
  pr.cov2d[1] = JC[0][0] * pr.J[1][0] + JC[0][1] * pr.J[1][1] + JC[0][2] * pr.J[1][2];
  pr.cov2d[2] = JC[1][0] * pr.J[1][0] + JC[1][1] * pr.J[1][1] + JC[1][2] * pr.J[1][2] + eps;
}

// Projects one Gaussian. `colors` points at its RGB (sh_degree < 0) or its K x 3 SH
// coefficients. Returns false (and an empty box) when the Gaussian is culled: non-finite
// input, camera z outside [near, far], degenerate 2D covariance, off screen, or too faint
// to ever reach alpha 1/255.
template <typename S>
II_HD bool project_gaussian(const ViewConsts<S>& cam, const S* mean, const S* quat, const S* scale, S opacity,
                            const S* colors, int sh_degree, int num_coeffs, Splat2D<S>& out, PixelBox& box) {
  box = PixelBox{};
  bool finite = s_finite(opacity);
  for (int i = 0; i < 3; ++i) finite = finite && s_finite(mean[i]) && s_finite(scale[i]);
  for (int i = 0; i < 4; ++i) finite = finite && s_finite(quat[i]);
  const int ncol = sh_degree < 0 ? 3 : num_coeffs * 3;
  for (int i = 0; i < ncol; ++i) finite = finite && s_finite(colors[i]);
  if (!finite) return false;

  Projection<S> pr;
  project_geometry(cam, mean, quat, scale, pr);
  const S z = pr.p.z;
  if (!(z >= cam.near_plane && z <= cam.far_plane)) return false;

  const S a = pr.cov2d[0], b = pr.cov2d[1], c = pr.cov2d[2];
  const S det = a * c - b * b;
  if (!(det > S(0)) || !s_finite(det)) return false;
  const S inv_det = S(1) / det;
  out.A = c * inv_det;
  out.B = -b * inv_det;
  out.C = a * inv_det;
  const S rz = S(1) / z;
  out.mx = cam.fx * pr.p.x * rz + cam.cx;
  out.my = cam.fy * pr.p.y * rz + cam.cy;
  out.depth = z;
  out.opacity = opacity;
  if (!s_finite(out.mx) || !s_finite(out.my) || !s_finite(out.A) || !s_finite(out.B) || !s_finite(out.C))
    return false;
  if (!(opacity >= S(kAlphaMin))) return false;  // alpha = opacity * (<= 1) never reaches 1/255

  // gsplat's footprint: 3 sigma of the larger eigenvalue, as whole tiles (in S, as gsplat
  // computes it in float).
  const S half = S(0.5) * (a + c);
  const S v1 = half + s_sqrt(s_max(S(0.01), half * half - det));
  const S radius = s_ceil(S(kSigmaExtent) * s_sqrt(v1));
  const S mx = out.mx, my = out.my;
  if (!(radius > S(0)) || mx + radius <= S(0) || mx - radius >= cam.width || my + radius <= S(0) ||
      my - radius >= cam.height)
    return false;
  const S ts = S(kTileSize);
  const int tw = cam.tiles_x, th = cam.tiles_y;
  const int tx0 = clamp_int(s_floor(mx / ts - radius / ts), 0, tw);
  const int tx1 = clamp_int(s_ceil(mx / ts + radius / ts), 0, tw);
  const int ty0 = clamp_int(s_floor(my / ts - radius / ts), 0, th);
  const int ty1 = clamp_int(s_ceil(my / ts + radius / ts), 0, th);

  // Inside those tiles only pixels in the ellipse alpha >= 1/255 ever contribute:
  // opacity * exp(-q/2) >= 1/255  <=>  q <= 2 ln(255 opacity), whose bounding box has half
  // widths sqrt(2 ln(255 o) cov_xx) and sqrt(2 ln(255 o) cov_yy). Pixel j is inside when its
  // centre j + 0.5 is; a relative margin far above rounding error keeps the box
  // conservative, so it changes only speed, never the image.
  out.level = s_log(opacity * S(1.0 / kAlphaMin));
  const S level = S(2) * out.level;
  const S ex = s_sqrt(level * a) * S(1.001) + S(1e-3), ey = s_sqrt(level * c) * S(1.001) + S(1e-3);
  const int x_lo = tx0 * kTileSize, x_hi = tx1 * kTileSize < cam.width_px ? tx1 * kTileSize : cam.width_px;
  const int y_lo = ty0 * kTileSize, y_hi = ty1 * kTileSize < cam.height_px ? ty1 * kTileSize : cam.height_px;
  box.x0 = clamp_int(s_ceil(mx - ex - S(0.5)), x_lo, x_hi);
  box.x1 = clamp_int(s_floor(mx + ex - S(0.5)) + S(1), x_lo, x_hi);
  box.y0 = clamp_int(s_ceil(my - ey - S(0.5)), y_lo, y_hi);
  box.y1 = clamp_int(s_floor(my + ey - S(0.5)) + S(1), y_lo, y_hi);
  if (box.empty()) {
    box = PixelBox{};
    return false;
  }

  if (sh_degree < 0) {
    for (int i = 0; i < 3; ++i) out.rgb[i] = colors[i];
  } else {
    sh_to_color(sh_degree, colors, mean[0] - cam.campos[0], mean[1] - cam.campos[1], mean[2] - cam.campos[2],
                out.rgb);
  }
  return true;
}

// Gradients of the loss with respect to one projected splat.
template <typename S>
// No default member initialisers, so that large buffers of it can stay uninitialised;
// write Splat2DGrad<S>{} for a zero value.
struct Splat2DGrad {
  S mx, my, A, B, C, depth, opacity, rgb[3];
};

// VJP of project_gaussian for a visible Gaussian: adds into v_mean (3), v_quat (4),
// v_scale (3), v_opacity and v_colors (3, or K x 3).
template <typename S>
II_HD void project_gaussian_vjp(const ViewConsts<S>& cam, const S* mean, const S* quat, const S* scale,
                                const S* colors, int sh_degree, const Splat2DGrad<S>& g, S* v_mean, S* v_quat,
                                S* v_scale, S* v_opacity, S* v_colors) {
  Projection<S> pr;
  project_geometry(cam, mean, quat, scale, pr);
  const S x = pr.p.x, y = pr.p.y, z = pr.p.z;
  const S rz = S(1) / z, rz2 = rz * rz;
  const S fx = cam.fx, fy = cam.fy;

  *v_opacity += g.opacity;
  S v_dir[3] = {0, 0, 0};
  if (sh_degree < 0) {
    for (int i = 0; i < 3; ++i) v_colors[i] += g.rgb[i];
  } else {
    sh_to_color_vjp(sh_degree, colors, mean[0] - cam.campos[0], mean[1] - cam.campos[1], mean[2] - cam.campos[2],
                    g.rgb, v_colors, v_dir);
  }

  // conic Q = cov2d^-1: dQ = -Q dCov Q, so dL/dCov = -Q G Q with G the symmetric matrix
  // gradient of Q (the off-diagonal B appears twice, so G01 = G10 = dL/dB / 2).
  const S a = pr.cov2d[0], b = pr.cov2d[1], c = pr.cov2d[2];
  const S inv_det = S(1) / (a * c - b * b);
  const S Q[2][2] = {{c * inv_det, -b * inv_det}, {-b * inv_det, a * inv_det}};
  const S G[2][2] = {{g.A, S(0.5) * g.B}, {S(0.5) * g.B, g.C}};
  S QG[2][2], VC[2][2];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) QG[i][j] = Q[i][0] * G[0][j] + Q[i][1] * G[1][j];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) VC[i][j] = -(QG[i][0] * Q[0][j] + QG[i][1] * Q[1][j]);

  // cov2d = J Cc J^T: dL/dCc = J^T VC J, dL/dJ = 2 VC J Cc (VC, Cc symmetric).
  M3<S> v_cc;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      S s = 0;
      for (int k = 0; k < 2; ++k)
        for (int l = 0; l < 2; ++l) s += pr.J[k][i] * VC[k][l] * pr.J[l][j];
      v_cc.m[i][j] = s;
    }
  S JC[2][3], vJ[2][3];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j)
      JC[i][j] = pr.J[i][0] * pr.cov_cam.m[0][j] + pr.J[i][1] * pr.cov_cam.m[1][j] + pr.J[i][2] * pr.cov_cam.m[2][j];
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j) vJ[i][j] = S(2) * (VC[i][0] * JC[0][j] + VC[i][1] * JC[1][j]);

  // Camera-space mean: from the 2D mean, the Jacobian and the depth output.
  S vp[3];
  vp[0] = fx * rz * g.mx;
  vp[1] = fy * rz * g.my;
  vp[2] = -(fx * x * g.mx + fy * y * g.my) * rz2 + g.depth;
  // J00 = fx/z, J11 = fy/z, J02 = -fx uc/z with uc = x/z unless clamped (then constant).
  vp[2] += -fx * rz2 * vJ[0][0] - fy * rz2 * vJ[1][1];
  if (!pr.clamp_x) {
    vp[0] += -fx * rz2 * vJ[0][2];
    vp[2] += S(2) * fx * x * rz2 * rz * vJ[0][2];
  } else {
    vp[2] += -pr.J[0][2] * rz * vJ[0][2];
  }
  if (!pr.clamp_y) {
    vp[1] += -fy * rz2 * vJ[1][2];
    vp[2] += S(2) * fy * y * rz2 * rz * vJ[1][2];
  } else {
    vp[2] += -pr.J[1][2] * rz * vJ[1][2];
  }

  // p = W m + t; plus the SH view direction m - campos.
  const M3<S>& W = cam.W;
  for (int i = 0; i < 3; ++i)
    v_mean[i] += W.m[0][i] * vp[0] + W.m[1][i] * vp[1] + W.m[2][i] * vp[2] + v_dir[i];

  // Cc = W Sigma W^T: dL/dSigma = W^T v_cc W. Sigma = M M^T: dL/dM = 2 dL/dSigma M.
  const M3<S> v_sigma = mul(mul_at(W, v_cc), W);
  M3<S> Mm;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) Mm.m[i][j] = pr.rot.m[i][j] * scale[j];
  const M3<S> vM = mul(v_sigma, Mm);  // times 2 below
  M3<S> vR;
  for (int j = 0; j < 3; ++j) {
    S vs = 0;
    for (int i = 0; i < 3; ++i) {
      vR.m[i][j] = S(2) * vM.m[i][j] * scale[j];
      vs += S(2) * vM.m[i][j] * pr.rot.m[i][j];
    }
    v_scale[j] += vs;
  }
  S vqn[4];
  quat_to_rotation_vjp(pr.qn[0], pr.qn[1], pr.qn[2], pr.qn[3], vR, vqn);
  // qn = q / |q|: dL/dq = (vqn - qn (qn . vqn)) / |q|; zero for the degenerate zero quaternion.
  if (pr.qnorm > S(kQuatNormMin)) {
    const S dot = vqn[0] * pr.qn[0] + vqn[1] * pr.qn[1] + vqn[2] * pr.qn[2] + vqn[3] * pr.qn[3];
    for (int i = 0; i < 4; ++i) v_quat[i] += (vqn[i] - dot * pr.qn[i]) / pr.qnorm;
  }
}

// Alpha of splat `s` at the pixel centre (px, py), or 0 when it is skipped (below 1/255,
// or a negative exponent from rounding). `vis` = exp(-sigma), `raw` = opacity * vis.
template <typename S>
II_HD S splat_alpha(const Splat2D<S>& s, S px, S py, S& dx, S& dy, S& vis, S& raw) {
  dx = s.mx - px;
  dy = s.my - py;
  const S sigma = S(0.5) * (s.A * dx * dx + s.C * dy * dy) + s.B * dx * dy;
  if (sigma < S(0)) return S(0);
  vis = s_exp(-sigma);
  raw = s.opacity * vis;
  const S alpha = s_min(S(kAlphaMax), raw);
  return alpha < S(kAlphaMin) ? S(0) : alpha;
}

// The columns [x0, x1) of the pixel row with centre `fy` in which splat `s` can reach
// alpha >= 1/255: sigma(dx) = A dx²/2 + B dy dx + C dy²/2 <= level is an interval in dx.
// Widened by a margin far above rounding error, so skipping the columns outside changes
// nothing but speed. Empty (x0 >= x1) when the row misses the ellipse.
template <typename S>
II_HD void row_span(const Splat2D<S>& s, S fy, int& x0, int& x1) {
  const S dy = s.my - fy;
  const S b = s.B * dy;
  const S disc = b * b - s.A * (s.C * dy * dy - S(2) * s.level);
  if (!(disc >= S(0))) {
    x0 = x1 = 0;
    return;
  }
  const S root = s_sqrt(disc);
  const S inv_a = S(1) / s.A;
  // Pixel centres px + 0.5 = mx - dx for dx between the roots (-b -+ root) / A.
  const S lo = s.mx - (-b + root) * inv_a - S(0.5), hi = s.mx - (-b - root) * inv_a - S(0.5);
  const S margin = S(1e-3) + S(1e-4) * (hi - lo + s_max(s_max(s.mx, -s.mx), S(1)));
  x0 = clamp_int(s_ceil(lo - margin), -1, 1 << 30);
  x1 = clamp_int(s_floor(hi + margin) + S(1), -1, 1 << 30);
}

}  // namespace ii::splat
