// FID and KID statistics on synthetic features with closed-form answers.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/LU>

#include "eval/fid.h"
#include "test_support.h"

namespace ii {
namespace {

FeatureMatrix random_features(int rows, int cols, uint64_t seed, double scale = 1.0) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, scale);
  FeatureMatrix m(rows, cols);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) m(i, j) = normal(rng);
  return m;
}

TEST(Fid, StatsAreMeanAndUnbiasedCovariance) {
  FeatureMatrix f(4, 2);
  f << 1, 2, 3, 2, 5, 6, 7, 6;
  const GaussianStats s = gaussian_stats(f);
  EXPECT_EQ(s.count, 4);
  EXPECT_DOUBLE_EQ(s.mean(0), 4.0);
  EXPECT_DOUBLE_EQ(s.mean(1), 4.0);
  // Deviations (-3,-2) (-1,-2) (1,2) (3,2): sums of products 20, 16, 16 over n - 1 = 3.
  EXPECT_NEAR(s.cov(0, 0), 20.0 / 3, 1e-12);
  EXPECT_NEAR(s.cov(0, 1), 16.0 / 3, 1e-12);
  EXPECT_NEAR(s.cov(1, 0), 16.0 / 3, 1e-12);
  EXPECT_NEAR(s.cov(1, 1), 16.0 / 3, 1e-12);
}

TEST(Fid, CommutingCovariances) {
  // Diagonal covariances: |Δμ|² + Σ (√a − √b)².
  GaussianStats x, y;
  x.mean = Eigen::Vector3d(1, 2, 3);
  y.mean = Eigen::Vector3d(0, 2, 5);
  x.cov = Eigen::Vector3d(4, 9, 1).asDiagonal();
  y.cov = Eigen::Vector3d(1, 16, 1).asDiagonal();
  const double expected = 1 + 0 + 4 + (2 - 1) * (2 - 1) + (3 - 4) * (3 - 4) + 0;
  EXPECT_NEAR(frechet_distance(x, y), expected, 1e-10);
  EXPECT_NEAR(frechet_distance(x, x), 0.0, 1e-10);
}

TEST(Fid, NonCommutingTwoByTwo) {
  // For 2x2 matrices, Tr √(S1 S2) = √(tr(S1 S2) + 2 √det(S1 S2)).
  GaussianStats x, y;
  x.mean = Eigen::Vector2d(0, 0);
  y.mean = Eigen::Vector2d(1, -1);
  x.cov.resize(2, 2);
  y.cov.resize(2, 2);
  x.cov << 2, 1, 1, 2;
  y.cov << 3, -1, -1, 1;
  const Eigen::Matrix2d p = x.cov * y.cov;
  const double trace_root = std::sqrt(p.trace() + 2 * std::sqrt(p.determinant()));
  const double expected = 2 + x.cov.trace() + y.cov.trace() - 2 * trace_root;
  EXPECT_NEAR(frechet_distance(x, y), expected, 1e-10);
  EXPECT_NEAR(frechet_distance(y, x), expected, 1e-10);  // symmetric
}

TEST(Fid, TranslatedSetIsTheSquaredShift) {
  // Same covariance: only the mean term remains; with fewer samples than dimensions the
  // feature path (nuclear norm) is used.
  const FeatureMatrix x = random_features(12, 30, 1);
  FeatureMatrix y = x;
  Eigen::RowVectorXd shift = Eigen::RowVectorXd::LinSpaced(30, -1.0, 2.0);
  y.rowwise() += shift;
  EXPECT_NEAR(frechet_distance(x, y), shift.squaredNorm(), 1e-8);
  const FeatureMatrix tall = random_features(50, 4, 2);
  FeatureMatrix tall_shifted = tall;
  tall_shifted.rowwise() += shift.head(4);
  EXPECT_NEAR(frechet_distance(tall, tall_shifted), shift.head(4).squaredNorm(), 1e-8);
}

TEST(Fid, FeaturePathAgreesWithStatistics) {
  // Rank-deficient covariances (fewer samples than dimensions), as with 40 test views and
  // 2048 features.
  const FeatureMatrix x = random_features(9, 25, 3), y = random_features(7, 25, 4, 1.5);
  const double from_features = frechet_distance(x, y);
  const double from_stats = frechet_distance(gaussian_stats(x), gaussian_stats(y));
  EXPECT_NEAR(from_features, from_stats, 1e-7 * std::abs(from_stats));
  EXPECT_GT(from_features, 0);
}

TEST(Kid, HandComputedSmallSets) {
  // d = 1, k(x, y) = (xy + 1)³. x = {0, 1}, y = {0, 2}:
  // off-diagonal k(x): k(0,1) = 1 twice -> 2 / (2·1) = 1; same for y;
  // cross: 1 + 1 + 1 + 27 = 30 -> 2·30 / 4 = 15. MMD² = 1 + 1 − 15 = −13.
  FeatureMatrix x(2, 1), y(2, 1);
  x << 0, 1;
  y << 0, 2;
  EXPECT_NEAR(polynomial_mmd_unbiased(x, y), -13.0, 1e-12);
}

TEST(Kid, MomentFormulaInOneDimension) {
  // In 1-D, k = 1 + 3xy + 3x²y² + x³y³, so the unbiased MMD² is
  // Σ_j c_j [(S_j(x)² − S_2j(x)) / (m(m−1)) + (same for y) − 2 S_j(x) S_j(y) / (mn)], c = (3, 3, 1).
  const FeatureMatrix x = random_features(13, 1, 5), y = random_features(9, 1, 6, 0.7);
  auto power_sum = [](const FeatureMatrix& f, int j) {
    double s = 0;
    for (int i = 0; i < f.rows(); ++i) s += std::pow(f(i, 0), j);
    return s;
  };
  const double m = x.rows(), n = y.rows();
  double expected = 0;
  const double c[4] = {0, 3, 3, 1};
  for (int j = 1; j <= 3; ++j)
    expected += c[j] * ((power_sum(x, j) * power_sum(x, j) - power_sum(x, 2 * j)) / (m * (m - 1)) +
                        (power_sum(y, j) * power_sum(y, j) - power_sum(y, 2 * j)) / (n * (n - 1)) -
                        2 * power_sum(x, j) * power_sum(y, j) / (m * n));
  EXPECT_NEAR(polynomial_mmd_unbiased(x, y), expected, 1e-10 * std::max(1.0, std::abs(expected)));
}

TEST(Kid, SubsetsOfTheWholeSetGiveTheFullEstimate) {
  const FeatureMatrix x = random_features(20, 8, 7), y = random_features(15, 8, 8, 1.3);
  KidOptions o;
  o.subsets = 5;
  o.subset_size = 1000;  // capped at 15: every subset of y is all of y...
  const KidResult r = kernel_inception_distance(x, y, o);
  EXPECT_EQ(r.subset_size, 15);
  EXPECT_EQ(r.subsets, 5);
  // ... and with equal set sizes every subset is the whole set.
  const FeatureMatrix x15 = x.topRows(15);
  const KidResult same = kernel_inception_distance(x15, y, o);
  EXPECT_NEAR(same.mean, polynomial_mmd_unbiased(x15, y), 1e-12);
  EXPECT_NEAR(same.std, 0.0, 1e-12);
  // Reproducible for a seed.
  EXPECT_EQ(kernel_inception_distance(x, y, o).mean, r.mean);
}

TEST(Kid, SameDistributionIsNearZeroAndShiftIsPositive) {
  const FeatureMatrix x = random_features(400, 16, 9), y = random_features(400, 16, 10);
  KidOptions o;
  o.subsets = 10;
  o.subset_size = 200;
  const KidResult same = kernel_inception_distance(x, y, o);
  FeatureMatrix shifted = y;
  shifted.array() += 1.0;
  const KidResult different = kernel_inception_distance(x, shifted, o);
  EXPECT_LT(std::abs(same.mean), 0.05 * different.mean);
  EXPECT_GT(different.mean, 0.1);
}

TEST(FidKid, BadInputsNameTheProblem) {
  const FeatureMatrix one = random_features(1, 4, 11), three = random_features(3, 4, 12),
                      other = random_features(3, 5, 13);
  EXPECT_EQ(test::error_message([&] { frechet_distance(one, three); }),
            "FID: needs at least 2 feature vectors per set, got 1 and 3");
  EXPECT_EQ(test::error_message([&] { frechet_distance(three, other); }), "FID: feature dimensions differ: 4 vs 5");
  FeatureMatrix bad = three;
  bad(1, 2) = std::nan("");
  EXPECT_EQ(test::error_message([&] { kernel_inception_distance(bad, three); }),
            "KID: features contain NaN or infinite values");
  EXPECT_EQ(test::error_message([&] { gaussian_stats(one); }),
            "feature statistics: needs at least 2 feature vectors, got 1");
  KidOptions o;
  o.subsets = 0;
  EXPECT_EQ(test::error_message([&] { kernel_inception_distance(three, three, o); }),
            "KID: needs at least 1 subset of at least 2 (got 0 of 1000)");
}

}  // namespace
}  // namespace ii
