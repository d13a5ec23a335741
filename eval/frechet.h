#pragma once
// Fréchet distance between two Gaussian fits of feature sets (FID, FVD) --
// pytorch-fid's conventions, docs/EVAL.md:
//   d^2 = ||mu1 - mu2||^2 + tr(S1) + tr(S2) - 2 tr sqrt(S1 S2)
// with mu the mean and S the unbiased covariance (divides by N - 1, as np.cov)
// in float64. tr sqrt(S1 S2) = sum_i sqrt(lambda_i(A)), A = sqrt(S1) S2
// sqrt(S1) (symmetric PSD), computed by two symmetric eigendecompositions with
// negative eigenvalues clamped to 0; this equals the trace of
// scipy.linalg.sqrtm(S1 @ S2) that pytorch-fid takes (tested to 1e-6 relative).
//
// Feature statistics can be saved and reused ("reference statistics"): two .npy
// files <prefix>_mu.npy (float64, shape (D,)) and <prefix>_sigma.npy (float64,
// shape (D, D)), the arrays pytorch-fid stores in its .npz as `mu` and `sigma`.

#include <Eigen/Core>
#include <cstdint>
#include <string>

namespace geodrive {

struct FeatureStatistics {
  Eigen::VectorXd mean;  // D
  Eigen::MatrixXd cov;   // D x D, unbiased (N - 1)
  // Number of feature vectors the statistics came from (-1 when loaded from a
  // file).
  int64_t num_samples = -1;
  int dims() const { return static_cast<int>(mean.size()); }
};

// Throws InputError naming `what` unless `cov` is a covariance matrix:
// symmetric and positive semi-definite up to float64 rounding (relative
// tolerance 1e-9 of its largest entry). Cached statistics are checked with it.
void CheckCovariance(const Eigen::MatrixXd& cov, const std::string& what);

// Mean and unbiased covariance of N x D features (one sample per row). Throws
// InputError, naming `what`, when N <= D (the covariance would be singular:
// FID/FVD need more samples than feature dimensions), or on non-finite values.
FeatureStatistics ComputeFeatureStatistics(
    const Eigen::MatrixXd& features, const std::string& what = "features");

struct FrechetResult {
  double distance = 0;    // the Fréchet distance (FID/FVD value)
  double mean_term = 0;   // ||mu1 - mu2||^2
  double trace_term = 0;  // tr S1 + tr S2 - 2 tr sqrt(S1 S2)
  double trace_sqrt = 0;  // tr sqrt(S1 S2)
  bool eps_added =
      false;  // pytorch-fid's retry with 1e-6 I added to both covariances
  std::string BriefReport() const;
};

struct FrechetOptions {
  // pytorch-fid adds eps * I to both covariances when the result is not finite.
  double eps = 1e-6;
  void Check() const;
};

FrechetResult FrechetDistance(const FeatureStatistics& a,
                              const FeatureStatistics& b,
                              const FrechetOptions& options = {});

// tr sqrt(S1 S2) for symmetric PSD S1, S2 via eigendecompositions (exposed for
// tests).
double TraceSqrtProduct(const Eigen::MatrixXd& s1, const Eigen::MatrixXd& s2);

// Writes <prefix>_mu.npy and <prefix>_sigma.npy (float64).
void SaveFeatureStatistics(const std::string& prefix,
                           const FeatureStatistics& stats);
// Reads them back; throws InputError for missing files or inconsistent shapes.
FeatureStatistics LoadFeatureStatistics(const std::string& prefix);

}  // namespace geodrive
