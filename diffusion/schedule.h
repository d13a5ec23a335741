#pragma once
// CogVideoX noise schedule (diffusers CogVideoXDDIMScheduler /
// CogVideoXDPMScheduler, 5B config): scaled-linear betas, SNR shift,
// zero-terminal-SNR rescale, "trailing" timesteps, v-prediction. Everything
// here is float64 scalar math; the tensor updates live in diffusion/sampler.h.

#include <cstdint>
#include <string>
#include <vector>

namespace geodrive {
namespace diffusion {

struct ScheduleConfig {
  int num_train_timesteps = 1000;
  double beta_start =
      0.00085;  // "scaled_linear": linspace(sqrt(start), sqrt(end))^2
  double beta_end = 0.012;
  double snr_shift_scale = 1.0;      // 5B: 1.0 (2B: 3.0)
  bool rescale_zero_snr = true;      // rescale_betas_zero_snr
  bool set_alpha_to_one = true;      // alpha_bar(prev < 0) = 1
  std::string spacing = "trailing";  // "trailing" | "leading" | "linspace"
  void Check() const;
};

// ᾱ_t for t = 0..num_train_timesteps-1 (with zero-terminal-SNR, ᾱ[T-1] == 0
// exactly).
std::vector<double> AlphasCumprod(const ScheduleConfig& config);

// Inference timesteps, descending (trailing, S = 50: 999, 979, ..., 19).
std::vector<int64_t> InferenceTimesteps(const ScheduleConfig& config,
                                        int num_steps);

// ᾱ at `t`, or the final ᾱ (1 with set_alpha_to_one, else ᾱ_0) for t < 0.
double AlphaBarAt(const std::vector<double>& alphas_cumprod,
                  const ScheduleConfig& config,
                  int64_t t);

// DDIM (η = 0) with v-prediction: x0 = c_x0_x·x − c_x0_v·v; x_prev = a·x +
// b·x0.
struct DdimCoefficients {
  double x0_from_x = 0, x0_from_v = 0;  // √ᾱ_t, √(1−ᾱ_t)
  double a = 0, b = 0;  // √((1−ᾱ_p)/(1−ᾱ_t)), √ᾱ_p − √ᾱ_t·a
};
DdimCoefficients DdimStepCoefficients(double alpha_bar_t,
                                      double alpha_bar_prev);

// CogVideoXDPMScheduler (SDE DPM-Solver++(2M)):
//   x_prev = mult1·x − mult2·D + noise·ε, D = x0 (first step / last step) or
//   D = mult3·x0 − mult4·x0_old (second-order, when a previous x0 exists and
//   prev_t >= 0).
// Infinities at ᾱ = 0 or ᾱ_prev = 1 are left to IEEE arithmetic exactly as
// torch does.
struct DpmCoefficients {
  double x0_from_x = 0, x0_from_v = 0;
  double mult1 = 0, mult2 = 0, noise = 0;
  bool second_order = false;
  double mult3 = 0, mult4 = 0;
};
// `alpha_bar_back` < 0 means "no previous step".
DpmCoefficients DpmStepCoefficients(double alpha_bar_t,
                                    double alpha_bar_prev,
                                    double alpha_bar_back,
                                    bool prev_t_nonnegative);

// Dynamic CFG (use_dynamic_cfg): 1 + g·(1 − cos(π·((S − t)/S)^5))/2 with the
// raw timestep t.
double DynamicGuidanceScale(double guidance, int num_steps, int64_t timestep);

}  // namespace diffusion
}  // namespace geodrive
