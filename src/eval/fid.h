#pragma once
// Distribution distances between two sets of image features (rows = images, columns =
// feature dimensions; Inception-v3 pool features give 2048 columns):
//
//  * FID (Heusel et al. 2017): the Fréchet distance between Gaussians fitted to the sets,
//    |μx − μy|² + Tr(Σx + Σy − 2 (Σx Σy)^½), with unbiased (n − 1) covariances as numpy's
//    np.cov. Tr (Σx Σy)^½ is the sum of the square roots of the eigenvalues of
//    Σx^½ Σy Σx^½ (symmetric, positive semi-definite: no complex parts to discard); from
//    features with fewer samples than dimensions it is the nuclear norm of Yᵀ X for the
//    centred, (n − 1)^-½-scaled sets, which is exact and costs O(d n²). Rounding noise
//    below zero is clamped to 0.
//  * KID (Bińkowski et al. 2018): the unbiased estimate of the squared MMD with the cubic
//    polynomial kernel k(x, y) = (x·y / d + 1)³, averaged over random subsets of equal size
//    drawn without replacement from each set (clean-fid / torch-fidelity: 100 subsets of at
//    most 1000).
#include <cstdint>

#include <Eigen/Core>

namespace ii {

using FeatureMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct GaussianStats {
  Eigen::VectorXd mean;
  Eigen::MatrixXd cov;
  int64_t count = 0;
};

// Mean and unbiased covariance of the rows (needs at least 2 rows).
GaussianStats gaussian_stats(const FeatureMatrix& features);

// Fréchet distance between two Gaussians (same dimension).
double frechet_distance(const GaussianStats& x, const GaussianStats& y);
// FID from the features themselves (each set needs at least 2 rows, same columns).
double frechet_distance(const FeatureMatrix& x, const FeatureMatrix& y);

// Unbiased polynomial-kernel MMD² between two whole sets (each at least 2 rows).
double polynomial_mmd_unbiased(const FeatureMatrix& x, const FeatureMatrix& y);

struct KidOptions {
  int subsets = 100;
  int subset_size = 1000;  // capped at the smaller set's size
  uint64_t seed = 0;       // subsets are drawn with std::mt19937_64(seed): reproducible
};
struct KidResult {
  double mean = 0;  // the KID
  double std = 0;   // standard deviation over subsets
  int subsets = 0, subset_size = 0;
};
KidResult kernel_inception_distance(const FeatureMatrix& x, const FeatureMatrix& y, const KidOptions& options = {});

}  // namespace ii
