#pragma once
// Residual add and layer norm in one pass over each row (the transformer's step between two
// matrix products), instantiated by the instruction-set files (kernels_*.cpp) over isa.h:
// sum = x + residual (float), normed = (sum - mean) / sqrt(var + eps) in the input type. The
// unfused form reads and writes the row four times (convert, add, normalise, convert).
#include <cstdint>

#include "model/cpu/isa.h"
#include "model/cpu/kernels.h"

namespace ii::cpu_kernels {
namespace {

template <class Isa>
void add_layer_norm_row(const AddNormProblem& pr, int64_t row) {
  using In = typename Isa::In;
  using F = typename Isa::F;
  constexpr int W = Isa::W;
  const int64_t n = pr.dim, full = n / W * W;
  const float* x = pr.x + row * n;
  const In* r = pr.residual ? static_cast<const In*>(pr.residual) + row * n : nullptr;
  // Without a residual the row is x itself.
  const float* y = r ? pr.sum + row * n : x;
  In* out = static_cast<In*>(pr.normed) + row * n;

  F vsum = Isa::zero();
  float total = 0.0f;
  if (r) {
    float* ys = pr.sum + row * n;
    for (int64_t j = 0; j < full; j += W) {
      const F v = Isa::add(Isa::load(x + j), Isa::load_in_f(r + j));
      Isa::store(ys + j, v);
      vsum = Isa::add(vsum, v);
    }
    for (int64_t j = full; j < n; ++j) total += ys[j] = x[j] + Isa::from_in(r[j]);
  } else {
    for (int64_t j = 0; j < full; j += W) vsum = Isa::add(vsum, Isa::load(x + j));
    for (int64_t j = full; j < n; ++j) total += x[j];
  }
  const float mean = (Isa::hsum(vsum) + total) / static_cast<float>(n);

  // Two passes over a row in cache: the variance of the centred values, as LibTorch.
  const F vmean = Isa::set1(mean);
  F vsq = Isa::zero();
  float squares = 0.0f;
  for (int64_t j = 0; j < full; j += W) {
    const F c = Isa::sub(Isa::load(y + j), vmean);
    vsq = Isa::fmadd(c, c, vsq);
  }
  for (int64_t j = full; j < n; ++j) squares += (y[j] - mean) * (y[j] - mean);
  const float var = (Isa::hsum(vsq) + squares) / static_cast<float>(n);
  const float rstd = 1.0f / __builtin_sqrtf(var + pr.eps);

  const F vrstd = Isa::set1(rstd);
  for (int64_t j = 0; j < full; j += W) Isa::store_in(out + j, Isa::mul(Isa::sub(Isa::load(y + j), vmean), vrstd));
  for (int64_t j = full; j < n; ++j) out[j] = Isa::to_in((y[j] - mean) * rstd);
}

template <class Isa>
void run_add_layer_norm(const AddNormProblem& problem, ParallelFor parallel) {
  constexpr int64_t kRowsPerTask = 16;
  const int64_t tasks = (problem.rows + kRowsPerTask - 1) / kRowsPerTask;
  parallel(
      tasks,
      [](void* context, int64_t task) {
        const auto& pr = *static_cast<const AddNormProblem*>(context);
        const int64_t end = smaller(pr.rows, (task + 1) * kRowsPerTask);
        for (int64_t row = task * kRowsPerTask; row < end; ++row) add_layer_norm_row<Isa>(pr, row);
      },
      const_cast<AddNormProblem*>(&problem));
}

}  // namespace
}  // namespace ii::cpu_kernels
