#pragma once
// Tensor updates of the CogVideoX schedulers (coefficients:
// diffusion/schedule.h) and classifier-free guidance. Model output is
// v-prediction.

#include <ATen/core/Generator.h>
#include <ATen/core/Tensor.h>

#include "diffusion/schedule.h"

namespace geodrive {
namespace diffusion {

// CogVideoXDDIMScheduler.step (η = 0): x0 = √ᾱ_t·x − √(1−ᾱ_t)·v; returns a·x +
// b·x0.
at::Tensor DdimStep(const at::Tensor& v,
                    const at::Tensor& x,
                    double alpha_bar_t,
                    double alpha_bar_prev,
                    at::Tensor* x0_out = nullptr);

// CogVideoXDPMScheduler.step. `old_x0` undefined on the first step;
// `alpha_bar_back` < 0 when there is no previous timestep. Draws Gaussian noise
// from `gen` exactly as diffusers does (once, and a second time for the
// second-order update). Returns x_prev; *x0_out = the plain x0 estimate (the
// pipeline's next `old_pred_original_sample`).
at::Tensor DpmStep(const at::Tensor& v,
                   const at::Tensor& old_x0,
                   const at::Tensor& x,
                   double alpha_bar_t,
                   double alpha_bar_prev,
                   double alpha_bar_back,
                   bool prev_t_nonnegative,
                   at::Generator gen,
                   at::Tensor* x0_out);

// Guidance on a [uncond; cond] batch: u + g·(c − u).
at::Tensor ClassifierFreeGuidance(const at::Tensor& doubled, double guidance);

}  // namespace diffusion
}  // namespace geodrive
