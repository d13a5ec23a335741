#include "diffusion/schedule.h"

#include <cmath>

#include "geometry/util/status.h"

namespace geodrive {
namespace diffusion {

void ScheduleConfig::Check() const {
  GEODRIVE_CHECK_INPUT(num_train_timesteps >= 2,
                       "scheduler: num_train_timesteps must be >= 2");
  GEODRIVE_CHECK_INPUT(beta_start > 0 && beta_end > beta_start && beta_end < 1,
                       "scheduler: need 0 < beta_start < beta_end < 1");
  GEODRIVE_CHECK_INPUT(snr_shift_scale > 0,
                       "scheduler: snr_shift_scale must be positive");
  GEODRIVE_CHECK_INPUT(
      spacing == "trailing" || spacing == "leading" || spacing == "linspace",
      "scheduler: unknown timestep spacing '", spacing, "'");
}

std::vector<double> AlphasCumprod(const ScheduleConfig& c) {
  c.Check();
  const int n = c.num_train_timesteps;
  std::vector<double> ab(n);
  const double s0 = std::sqrt(c.beta_start), s1 = std::sqrt(c.beta_end);
  double prod = 1.0;
  for (int i = 0; i < n; ++i) {
    // torch.linspace(start, end, n) in float64: start + i * (end - start) / (n
    // - 1), with the second half computed from the end (torch's symmetric
    // formulation).
    const double step = (s1 - s0) / (n - 1);
    const double sq = i < n / 2 ? s0 + step * i : s1 - step * (n - 1 - i);
    const double beta = sq * sq;
    prod *= 1.0 - beta;
    ab[i] = prod;
  }
  const double s = c.snr_shift_scale;
  for (double& a : ab) a = a / (s + (1 - s) * a);
  if (c.rescale_zero_snr) {
    std::vector<double> sq(n);
    for (int i = 0; i < n; ++i) sq[i] = std::sqrt(ab[i]);
    const double a0 = sq[0], at = sq[n - 1];
    for (int i = 0; i < n; ++i) {
      double v = sq[i] - at;
      v *= a0 / (a0 - at);
      ab[i] = v * v;
    }
  }
  return ab;
}

std::vector<int64_t> InferenceTimesteps(const ScheduleConfig& c,
                                        int num_steps) {
  c.Check();
  const int n = c.num_train_timesteps;
  GEODRIVE_CHECK_INPUT(num_steps >= 1 && num_steps <= n,
                       "--steps must be in [1, ", n, "], got ", num_steps);
  std::vector<int64_t> ts;
  if (c.spacing == "trailing") {
    const double ratio = static_cast<double>(n) / num_steps;
    // np.round(np.arange(n, 0, -ratio)) - 1; numpy rounds half to even
    // (nearbyint).
    const int64_t len = static_cast<int64_t>(std::ceil((0.0 - n) / -ratio));
    for (int64_t k = 0; k < len; ++k) {
      ts.push_back(static_cast<int64_t>(std::nearbyint(n + k * -ratio)) - 1);
    }
  } else if (c.spacing == "leading") {
    const int64_t ratio = n / num_steps;
    for (int k = num_steps - 1; k >= 0; --k) ts.push_back(k * ratio);
  } else {  // linspace
    for (int k = num_steps - 1; k >= 0; --k) {
      const double v = num_steps == 1
                           ? 0.0
                           : static_cast<double>(n - 1) * k / (num_steps - 1);
      ts.push_back(static_cast<int64_t>(std::nearbyint(v)));
    }
  }
  return ts;
}

double AlphaBarAt(const std::vector<double>& ab,
                  const ScheduleConfig& c,
                  int64_t t) {
  if (t < 0) return c.set_alpha_to_one ? 1.0 : ab.front();
  GEODRIVE_CHECK_INPUT(t < static_cast<int64_t>(ab.size()),
                       "scheduler: timestep ", t, " out of range");
  return ab[t];
}

DdimCoefficients DdimStepCoefficients(double at, double ap) {
  DdimCoefficients k;
  k.x0_from_x = std::sqrt(at);
  k.x0_from_v = std::sqrt(1 - at);
  k.a = std::sqrt((1 - ap) / (1 - at));
  k.b = std::sqrt(ap) - std::sqrt(at) * k.a;
  return k;
}

DpmCoefficients DpmStepCoefficients(double at,
                                    double ap,
                                    double aback,
                                    bool prev_nonneg) {
  DpmCoefficients k;
  k.x0_from_x = std::sqrt(at);
  k.x0_from_v = std::sqrt(1 - at);
  const double lamb = std::log(std::sqrt(at / (1 - at)));
  const double lamb_next = std::log(std::sqrt(ap / (1 - ap)));
  const double h = lamb_next - lamb;
  k.mult1 = std::sqrt((1 - ap) / (1 - at)) * std::exp(-h);
  k.mult2 = std::expm1(-2 * h) * std::sqrt(ap);
  k.noise = std::sqrt(1 - ap) * std::sqrt(1 - std::exp(-2 * h));
  if (aback >= 0 && prev_nonneg) {
    const double lamb_prev = std::log(std::sqrt(aback / (1 - aback)));
    const double h_last = lamb - lamb_prev;
    const double r = h_last / h;
    k.second_order = true;
    k.mult3 = 1 + 1 / (2 * r);
    k.mult4 = 1 / (2 * r);
  }
  return k;
}

double DynamicGuidanceScale(double g, int num_steps, int64_t t) {
  const double S = num_steps;
  return 1 +
         g * ((1 - std::cos(M_PI *
                            std::pow((S - static_cast<double>(t)) / S, 5.0))) /
              2);
}

}  // namespace diffusion
}  // namespace geodrive
