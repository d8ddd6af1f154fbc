#include "eval/fid.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "common/error.h"

namespace ii {

namespace {

void check_sets(const FeatureMatrix& x, const FeatureMatrix& y, const char* what) {
  if (x.rows() < 2 || y.rows() < 2)
    fail("{}: needs at least 2 feature vectors per set, got {} and {}", what, x.rows(), y.rows());
  if (x.cols() != y.cols()) fail("{}: feature dimensions differ: {} vs {}", what, x.cols(), y.cols());
  if (!x.allFinite() || !y.allFinite()) fail("{}: features contain NaN or infinite values", what);
}

// Symmetric PSD square root by eigendecomposition (negative rounding noise clamped to 0).
Eigen::MatrixXd sqrt_psd(const Eigen::MatrixXd& m) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (m + m.transpose()));
  const Eigen::VectorXd roots = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return eig.eigenvectors() * roots.asDiagonal() * eig.eigenvectors().transpose();
}

// Rows minus their mean, scaled by (n - 1)^-1/2: X̃ᵀ X̃ is the unbiased covariance.
Eigen::MatrixXd centred_scaled(const FeatureMatrix& f) {
  const Eigen::RowVectorXd mean = f.colwise().mean();
  return (f.rowwise() - mean) / std::sqrt(double(f.rows() - 1));
}

}  // namespace

GaussianStats gaussian_stats(const FeatureMatrix& features) {
  if (features.rows() < 2) fail("feature statistics: needs at least 2 feature vectors, got {}", features.rows());
  if (!features.allFinite()) fail("feature statistics: features contain NaN or infinite values");
  GaussianStats s;
  s.count = features.rows();
  s.mean = features.colwise().mean().transpose();
  const Eigen::MatrixXd c = centred_scaled(features);
  s.cov = c.transpose() * c;
  return s;
}

double frechet_distance(const GaussianStats& x, const GaussianStats& y) {
  const auto d = x.mean.size();
  if (y.mean.size() != d || x.cov.rows() != d || x.cov.cols() != d || y.cov.rows() != d || y.cov.cols() != d)
    fail("Fréchet distance: statistics of different dimensions ({} and {})", d, y.mean.size());
  const Eigen::MatrixXd root_x = sqrt_psd(x.cov);
  const Eigen::MatrixXd inner = root_x * y.cov * root_x;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (inner + inner.transpose()), Eigen::EigenvaluesOnly);
  const double trace_root = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().sum();
  // Non-negative in exact arithmetic; clamp the rounding noise of equal distributions.
  return std::max(0.0, (x.mean - y.mean).squaredNorm() + x.cov.trace() + y.cov.trace() - 2.0 * trace_root);
}

double frechet_distance(const FeatureMatrix& x, const FeatureMatrix& y) {
  check_sets(x, y, "FID");
  const auto d = x.cols();
  if (std::min(x.rows(), y.rows()) - 1 >= d) return frechet_distance(gaussian_stats(x), gaussian_stats(y));
  // Σx = Aᵀ A, Σy = Bᵀ B: the non-zero eigenvalues of Σx Σy are those of (B Aᵀ)ᵀ (B Aᵀ),
  // so Tr (Σx Σy)^½ = the sum of the singular values of B Aᵀ.
  const Eigen::MatrixXd a = centred_scaled(x), b = centred_scaled(y);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(b * a.transpose());
  const double trace_root = svd.singularValues().sum();
  const Eigen::VectorXd mean_gap = (x.colwise().mean() - y.colwise().mean()).transpose();
  return std::max(0.0, mean_gap.squaredNorm() + a.squaredNorm() + b.squaredNorm() - 2.0 * trace_root);
}

double polynomial_mmd_unbiased(const FeatureMatrix& x, const FeatureMatrix& y) {
  check_sets(x, y, "KID");
  const double d = double(x.cols());
  auto kernel = [d](const FeatureMatrix& p, const FeatureMatrix& q) -> Eigen::MatrixXd {
    return ((p * q.transpose()).array() / d + 1.0).cube().matrix();
  };
  const Eigen::MatrixXd kxx = kernel(x, x), kyy = kernel(y, y), kxy = kernel(x, y);
  const double m = double(x.rows()), n = double(y.rows());
  return (kxx.sum() - kxx.trace()) / (m * (m - 1)) + (kyy.sum() - kyy.trace()) / (n * (n - 1)) -
         2.0 * kxy.sum() / (m * n);
}

KidResult kernel_inception_distance(const FeatureMatrix& x, const FeatureMatrix& y, const KidOptions& options) {
  check_sets(x, y, "KID");
  if (options.subsets < 1 || options.subset_size < 2)
    fail("KID: needs at least 1 subset of at least 2 (got {} of {})", options.subsets, options.subset_size);
  KidResult r;
  r.subsets = options.subsets;
  r.subset_size = static_cast<int>(std::min<int64_t>({options.subset_size, x.rows(), y.rows()}));
  std::mt19937_64 rng(options.seed);
  auto draw = [&](const FeatureMatrix& f) {
    std::vector<int64_t> order(static_cast<size_t>(f.rows()));
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    FeatureMatrix subset(r.subset_size, f.cols());
    for (int i = 0; i < r.subset_size; ++i) subset.row(i) = f.row(order[i]);
    return subset;
  };
  std::vector<double> values;
  for (int s = 0; s < options.subsets; ++s) {
    const FeatureMatrix xs = draw(x), ys = draw(y);
    values.push_back(polynomial_mmd_unbiased(xs, ys));
  }
  r.mean = std::accumulate(values.begin(), values.end(), 0.0) / values.size();
  double var = 0;
  for (double v : values) var += (v - r.mean) * (v - r.mean);
  r.std = std::sqrt(var / values.size());
  return r;
}

}  // namespace ii
