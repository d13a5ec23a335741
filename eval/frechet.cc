#include "eval/frechet.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "geometry/npy.h"
#include "geometry/util/status.h"

namespace geodrive {
namespace {

// Symmetric square root of a symmetric PSD matrix (negative eigenvalues clamped
// to 0).
Eigen::MatrixXd SymmetricSqrt(const Eigen::MatrixXd& s) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(s);
  const Eigen::VectorXd root = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return eig.eigenvectors() * root.asDiagonal() *
         eig.eigenvectors().transpose();
}

}  // namespace

void CheckCovariance(const Eigen::MatrixXd& cov, const std::string& what) {
  // Tolerances relative to the matrix's scale (its largest |entry|): a
  // covariance computed in float64 is symmetric to rounding and its smallest
  // eigenvalue is >= -1e-9 of the scale; a file outside that is not one (a
  // sign flip, a transposed block, another array), and its Frechet distance
  // would be meaningless (negative, or millions off).
  const double scale = std::max(cov.cwiseAbs().maxCoeff(), 1e-300);
  const double asym = (cov - cov.transpose()).cwiseAbs().maxCoeff();
  GEODRIVE_CHECK_INPUT(asym <= 1e-9 * scale, what,
                       ": not a covariance matrix: not symmetric (largest "
                       "|S - S^T| entry ",
                       asym, ", largest |S| entry ", scale, ")");
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(cov,
                                                     Eigen::EigenvaluesOnly);
  const double lowest = eig.eigenvalues().minCoeff();
  GEODRIVE_CHECK_INPUT(lowest >= -1e-9 * scale * cov.rows(), what,
                       ": not a covariance matrix: eigenvalue ", lowest,
                       " < 0 (not positive semi-definite)");
}

FeatureStatistics ComputeFeatureStatistics(const Eigen::MatrixXd& features,
                                           const std::string& what) {
  const int64_t n = features.rows();
  const int64_t d = features.cols();
  GEODRIVE_CHECK_INPUT(d > 0, what, ": features have no dimensions");
  GEODRIVE_CHECK_INPUT(n > d, what, ": ", n, " samples for ", d,
                       "-dimensional features: the covariance needs more "
                       "samples than dimensions "
                       "(at least ",
                       d + 1, "), refusing to return a meaningless distance");
  GEODRIVE_CHECK_INPUT(features.allFinite(), what,
                       ": features contain NaN or Inf");
  FeatureStatistics stats;
  stats.num_samples = n;
  stats.mean = features.colwise().mean().transpose();
  const Eigen::MatrixXd centred = features.rowwise() - stats.mean.transpose();
  stats.cov = (centred.transpose() * centred) / static_cast<double>(n - 1);
  return stats;
}

void FrechetOptions::Check() const {
  GEODRIVE_CHECK_INPUT(eps >= 0 && std::isfinite(eps),
                       "frechet: eps must be >= 0");
}

std::string FrechetResult::BriefReport() const {
  std::ostringstream os;
  os << "Frechet distance " << distance << " (mean term " << mean_term
     << ", trace term " << trace_term << (eps_added ? ", eps added" : "")
     << ")";
  return os.str();
}

double TraceSqrtProduct(const Eigen::MatrixXd& s1, const Eigen::MatrixXd& s2) {
  const Eigen::MatrixXd r1 = SymmetricSqrt(s1);
  Eigen::MatrixXd a = r1 * s2 * r1;
  a = 0.5 * (a + a.transpose());  // exactly symmetric
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(a, Eigen::EigenvaluesOnly);
  return eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().sum();
}

FrechetResult FrechetDistance(const FeatureStatistics& a,
                              const FeatureStatistics& b,
                              const FrechetOptions& options) {
  options.Check();
  const int d = a.dims();
  GEODRIVE_CHECK_INPUT(d > 0 && a.cov.rows() == d && a.cov.cols() == d,
                       "frechet: the first "
                       "statistics are inconsistent (mean ",
                       a.mean.size(), ", covariance ", a.cov.rows(), "x",
                       a.cov.cols(), ")");
  GEODRIVE_CHECK_INPUT(b.dims() == d && b.cov.rows() == d && b.cov.cols() == d,
                       "frechet: feature dimensions differ (", d, " vs ",
                       b.dims(), ")");
  GEODRIVE_CHECK_INPUT(a.mean.allFinite() && a.cov.allFinite() &&
                           b.mean.allFinite() && b.cov.allFinite(),
                       "frechet: statistics contain NaN or Inf");
  FrechetResult r;
  r.mean_term = (a.mean - b.mean).squaredNorm();
  r.trace_sqrt = TraceSqrtProduct(a.cov, b.cov);
  if (!std::isfinite(r.trace_sqrt)) {
    const Eigen::MatrixXd offset =
        options.eps * Eigen::MatrixXd::Identity(d, d);
    r.trace_sqrt = TraceSqrtProduct(a.cov + offset, b.cov + offset);
    r.eps_added = true;
  }
  r.trace_term = a.cov.trace() + b.cov.trace() - 2.0 * r.trace_sqrt;
  r.distance = r.mean_term + r.trace_term;
  // The distance is >= 0 up to rounding of the traces; anything else means
  // the statistics were not covariances: an error, never a reported figure.
  const double tol = 1e-9 * (a.cov.trace() + b.cov.trace() + r.mean_term);
  GEODRIVE_CHECK_INPUT(std::isfinite(r.distance) && r.distance >= -tol,
                       "frechet: distance ", r.distance,
                       " is not a valid distance (the statistics are not "
                       "covariances of real features)");
  return r;
}

void SaveFeatureStatistics(const std::string& prefix,
                           const FeatureStatistics& stats) {
  const int64_t d = stats.dims();
  GEODRIVE_CHECK_INPUT(d > 0 && stats.cov.rows() == d && stats.cov.cols() == d,
                       prefix, ": inconsistent feature statistics");
  WriteNpy(prefix + "_mu.npy", NpyArray::Float64({d}, stats.mean.data()));
  // Row-major on disk; the covariance is symmetric but write it properly
  // anyway.
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>
      cov = stats.cov;
  WriteNpy(prefix + "_sigma.npy", NpyArray::Float64({d, d}, cov.data()));
}

FeatureStatistics LoadFeatureStatistics(const std::string& prefix) {
  const std::string mu_path = prefix + "_mu.npy",
                    sigma_path = prefix + "_sigma.npy";
  const NpyArray mu = ReadNpy(mu_path);
  const NpyArray sigma = ReadNpy(sigma_path);
  GEODRIVE_CHECK_INPUT(
      mu.dtype == NpyDtype::kFloat64 && mu.shape.size() == 1 && mu.shape[0] > 0,
      mu_path, ": expected a float64 array of shape (D,)");
  const int64_t d = mu.shape[0];
  GEODRIVE_CHECK_INPUT(
      sigma.dtype == NpyDtype::kFloat64 && sigma.shape.size() == 2 &&
          sigma.shape[0] == d && sigma.shape[1] == d,
      sigma_path, ": expected a float64 array of shape (", d, ", ", d, ")");
  FeatureStatistics stats;
  stats.mean = Eigen::Map<const Eigen::VectorXd>(mu.Data<double>(), d);
  stats.cov = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic,
                                             Eigen::Dynamic, Eigen::RowMajor>>(
      sigma.Data<double>(), d, d);
  GEODRIVE_CHECK_INPUT(stats.mean.allFinite(), mu_path,
                       ": contains NaN or Inf");
  GEODRIVE_CHECK_INPUT(stats.cov.allFinite(), sigma_path,
                       ": contains NaN or Inf");
  CheckCovariance(stats.cov, sigma_path);
  return stats;
}

}  // namespace geodrive
