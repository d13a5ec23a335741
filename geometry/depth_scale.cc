#include "geometry/depth_scale.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>

#include "geometry/util/status.h"

namespace geodrive {

void DepthScaleOptions::Check() const {
  GEODRIVE_CHECK_INPUT(ransac_iterations >= 1,
                       "depth scale: ransac_iterations must be >= 1");
  GEODRIVE_CHECK_INPUT(inlier_log_threshold > 0,
                       "depth scale: inlier_log_threshold must be > 0");
  GEODRIVE_CHECK_INPUT(irls_iterations >= 0,
                       "depth scale: irls_iterations must be >= 0");
  GEODRIVE_CHECK_INPUT(cauchy_scale > 0,
                       "depth scale: cauchy_scale must be > 0");
  GEODRIVE_CHECK_INPUT(min_points >= 1, "depth scale: min_points must be >= 1");
}

namespace {
double Median(std::vector<double> v) {
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  if (v.size() % 2 == 1) return v[mid];
  return 0.5 * (v[mid] + *std::max_element(v.begin(), v.begin() + mid));
}
// The p-quantile of sorted values (linear interpolation between the two
// nearest ranks); 0 when empty.
double SortedPercentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0;
  const double pos = p * (sorted.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - lo) * (sorted[hi] - sorted[lo]);
}

// How many values r of `sorted` (ascending, finite) satisfy |r - c| < thr:
// the same count as testing every value, found with two binary searches.
// The values that pass are one contiguous run: below c, c - r only shrinks as
// r grows (rounded subtraction is monotone), above c, r - c only grows.
int CountWithin(const std::vector<double>& sorted, double c, double thr) {
  const auto pass = [&](double r) { return std::abs(r - c) < thr; };
  const auto first =
      std::partition_point(sorted.begin(), sorted.end(),
                           [&](double r) { return r < c && !pass(r); });
  const auto last = std::partition_point(
      first, sorted.end(), [&](double r) { return r < c || pass(r); });
  return static_cast<int>(last - first);
}
}  // namespace

DepthScaleResult FitDepthScale(const std::vector<double>& d_ref,
                               const std::vector<double>& d_est,
                               const DepthScaleOptions& options) {
  options.Check();
  GEODRIVE_CHECK_INPUT(d_ref.size() == d_est.size(),
                       "depth scale: ", d_ref.size(), " reference depths but ",
                       d_est.size(), " estimated depths");
  DepthScaleResult result;
  std::vector<double> log_ratio, ref, est;
  for (size_t i = 0; i < d_ref.size(); ++i) {
    if (std::isfinite(d_ref[i]) && std::isfinite(d_est[i]) && d_ref[i] > 0 &&
        d_est[i] > 0) {
      log_ratio.push_back(std::log(d_ref[i] / d_est[i]));
      ref.push_back(d_ref[i]);
      est.push_back(d_est[i]);
    }
  }
  result.num_points = static_cast<int>(log_ratio.size());
  if (result.num_points < options.min_points) {
    result.message = "too few valid depth pairs (" +
                     std::to_string(result.num_points) + " < " +
                     std::to_string(options.min_points) + ")";
    return result;
  }
  const double thr = options.inlier_log_threshold;
  double log_s = Median(log_ratio);
  if (options.use_ransac) {
    // RANSAC over single-sample hypotheses, each scored by its inlier count:
    // counted on a sorted copy (O(log n) a hypothesis instead of O(n); the
    // counts, and so the result, are the same).
    std::vector<double> sorted = log_ratio;
    std::sort(sorted.begin(), sorted.end());
    auto count_inliers = [&](double c) { return CountWithin(sorted, c, thr); };
    std::mt19937_64 rng(options.seed);
    std::uniform_int_distribution<size_t> pick(0, log_ratio.size() - 1);
    int best = count_inliers(log_s);
    for (int it = 0; it < options.ransac_iterations; ++it) {
      const double candidate = log_ratio[pick(rng)];
      const int n = count_inliers(candidate);
      if (n > best) best = n, log_s = candidate;
    }
    std::vector<double> inl;
    for (double r : log_ratio)
      if (std::abs(r - log_s) < thr) inl.push_back(r);
    if (!inl.empty()) log_s = Median(inl);
  }
  // IRLS with Cauchy weights on the log residuals.
  for (int it = 0; it < options.irls_iterations; ++it) {
    double wsum = 0, wr = 0;
    for (double r : log_ratio) {
      const double e = (r - log_s) / options.cauchy_scale;
      const double w = 1.0 / (1.0 + e * e);
      wsum += w;
      wr += w * r;
    }
    if (wsum <= 0) break;
    const double next = wr / wsum;
    const bool converged = std::abs(next - log_s) < 1e-12;
    log_s = next;
    if (converged) break;
  }
  // Final least-squares refinement on the inliers only: outliers keep a small
  // Cauchy weight in IRLS, which biases the estimate slightly; the inlier mean
  // of log ratios does not.
  for (int it = 0; it < 3; ++it) {
    double sum = 0;
    int n = 0;
    for (double r : log_ratio) {
      if (std::abs(r - log_s) < thr) sum += r, ++n;
    }
    if (n == 0) break;
    log_s = sum / n;
  }
  result.scale = std::exp(log_s);
  if (!std::isfinite(result.scale) || result.scale <= 0) {
    result.message = "fitted scale is not finite and positive";
    return result;
  }
  std::vector<double> residuals;
  for (size_t i = 0; i < log_ratio.size(); ++i) {
    if (std::abs(log_ratio[i] - log_s) < thr) {
      residuals.push_back(std::abs(ref[i] - result.scale * est[i]));
    }
  }
  result.num_inliers = static_cast<int>(residuals.size());
  result.inlier_fraction =
      static_cast<double>(result.num_inliers) / result.num_points;
  std::sort(residuals.begin(), residuals.end());
  result.residual_p50 = SortedPercentile(residuals, 0.5);
  result.residual_p90 = SortedPercentile(residuals, 0.9);
  result.residual_p99 = SortedPercentile(residuals, 0.99);
  result.success = result.num_inliers >= options.min_points;
  result.message =
      result.success
          ? "ok"
          : "too few inliers (" + std::to_string(result.num_inliers) + ")";
  return result;
}

std::string DepthScaleResult::BriefReport() const {
  std::ostringstream os;
  if (!success) {
    os << "depth scale failed: " << message;
    return os.str();
  }
  os << "scale " << scale << ", " << num_inliers << "/" << num_points
     << " inliers (" << 100.0 * inlier_fraction << "%), |residual| p50 "
     << residual_p50 << " p90 " << residual_p90 << " p99 " << residual_p99;
  return os.str();
}

double SampleDepthBilinear(const cv::Mat& depth,
                           const cv::Mat& invalid_mask,
                           double u,
                           double v) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (!(u >= 0 && v >= 0)) return nan;
  const int x0 = static_cast<int>(std::floor(u)),
            y0 = static_cast<int>(std::floor(v));
  const int x1 = x0 + 1, y1 = y0 + 1;
  if (x1 >= depth.cols || y1 >= depth.rows) {
    // Exactly on the last row/column: allow when the fractional part is zero.
    if (!(x0 < depth.cols && y0 < depth.rows)) return nan;
  }
  const double ax = u - x0, ay = v - y0;
  double acc = 0, wsum = 0;
  for (int dy = 0; dy <= 1; ++dy) {
    for (int dx = 0; dx <= 1; ++dx) {
      const double w = (dx ? ax : 1 - ax) * (dy ? ay : 1 - ay);
      if (w == 0) continue;
      const int x = x0 + dx, y = y0 + dy;
      if (x >= depth.cols || y >= depth.rows) return nan;
      const float d = depth.at<float>(y, x);
      if (!std::isfinite(d) || d <= 0) return nan;
      if (!invalid_mask.empty() && invalid_mask.at<uint8_t>(y, x) != 0)
        return nan;
      acc += w * d;
      wsum += w;
    }
  }
  return wsum > 0 ? acc / wsum : nan;
}

}  // namespace geodrive
