// `geodrive-diffusion train`: trains the condition encoder on build-dataset
// pairs (diffusion/train.h, docs/DIFFUSION.md "Training").

#include <CLI/CLI.hpp>
#include <iostream>

#include "apps/cli/cli.h"
#include "diffusion/runtime_cli.h"
#include "diffusion/train.h"

namespace geodrive {
namespace diffusion {
namespace {

CommandRunner SetupTrain(CLI::App& sub) {
  // The options live as long as the process (the callback runs after parse).
  static TrainOptions o;
  static bool no_progress = false, no_cache = false, no_image_noise = false;
  static RuntimeArgs runtime;
  CLI::App* cmd = &sub;
  cmd->add_option("--pairs", o.pairs, "train manifest.jsonl (build-dataset)")
      ->required();
  cmd->add_option("--val-pairs", o.val_pairs,
                  "validation manifest.jsonl (fixed noise and timesteps)");
  cmd->add_option("--config", o.config,
                  "preset: cogvideox-5b-i2v, tiny or tiny-49")
      ->capture_default_str();
  cmd->add_option(
      "--weights", o.weights,
      "backbone checkpoint (.safetensors or .index.json; 'branch.*' "
      "tensors in it start the encoder). Default for tiny presets: "
      "random from --seed");
  cmd->add_option(
      "--branch-weights", o.branch_weights,
      "starting encoder (branch/diffusion_pytorch_model.safetensors)");
  cmd->add_option("--vae-weights", o.vae_weights,
                  "VAE checkpoint (diffusers vae/ names). Default for tiny "
                  "presets: random from --seed");
  cmd->add_option(
      "--prompt-embeds", o.prompt_embeds,
      "safetensors with 'prompt_embeds' [1, L, D] (default: zeros)");
  cmd->add_option("--out", o.out, "output folder")->required();
  cmd->add_option("--resume", o.resume,
                  "continue from a checkpoint-<step>/ folder (same --out)");
  cmd->add_option("--steps", o.steps, "total optimiser steps")
      ->capture_default_str();
  cmd->add_option("--batch", o.batch, "pairs per step")->capture_default_str();
  cmd->add_option("--lr", o.lr, "AdamW learning rate")->capture_default_str();
  cmd->add_option("--weight-decay", o.weight_decay, "AdamW weight decay")
      ->capture_default_str();
  cmd->add_option("--max-grad-norm", o.max_grad_norm,
                  "gradient-norm clipping (<= 0: off)")
      ->capture_default_str();
  cmd->add_option("--warmup-steps", o.warmup_steps,
                  "linear learning-rate warm-up steps")
      ->capture_default_str();
  cmd->add_option("--seed", o.seed, "data order, noise and timestep seed")
      ->capture_default_str();
  cmd->add_option("--val-every", o.val_every, "validation every N steps")
      ->capture_default_str();
  cmd->add_option("--val-timesteps", o.val_timesteps,
                  "fixed timesteps per validation pair")
      ->capture_default_str();
  cmd->add_option("--checkpoint-every", o.checkpoint_every,
                  "checkpoint every N steps (0: only at the end)")
      ->capture_default_str();
  cmd->add_flag("--grad-checkpointing", o.grad_checkpointing,
                "recompute the encoder and each backbone block in backward "
                "instead of keeping their activations");
  cmd->add_flag("--no-latent-cache", no_cache,
                "decode and VAE-encode the pairs every step through the "
                "prefetch queue instead of caching latents");
  cmd->add_option("--prefetch", o.prefetch, "decoded pairs queued ahead")
      ->capture_default_str();
  cmd->add_flag("--no-image-noise", no_image_noise,
                "no first-frame noise / image-latent dropout augmentation");
  cmd->add_option("--attention-chunk-mb", o.attention_chunk_mb,
                  "max attention-score memory per chunk (MB)")
      ->capture_default_str();
  cmd->add_flag("--no-progress", no_progress, "no progress line");
  AddRuntimeOptions(*cmd, &runtime, kRuntimeVae | kRuntimeAttention);
  return [] {
    o.runtime = runtime.Parse();
    o.attention = runtime.Attention();
    o.progress = !no_progress;
    o.cache_latents = !no_cache;
    o.image_noise = !no_image_noise;
    std::cout << Train(o).BriefReport() << std::endl;
    return 0;
  };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    train,
    "train",
    "Train the condition encoder on build-dataset pairs (frozen backbone and "
    "VAE, v-prediction MSE, AdamW); writes checkpoint-<step>/ and "
    "train_log.{csv,json}",
    SetupTrain);

}  // namespace diffusion
}  // namespace geodrive
