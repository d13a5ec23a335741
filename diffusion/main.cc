// `geodrive-diffusion`: the LibTorch diffusion runtime (CogVideoX-5B-I2V
// backbone + GeoDrive condition encoder). Subcommands: sample, init-weights,
// check-weights, names, train. Exit codes: 0 ok, 1 internal failure, 2 bad
// arguments or bad input.

#include <glog/logging.h>

#include <CLI/CLI.hpp>
#include <functional>
#include <iostream>

#include "diffusion/config.h"
#include "diffusion/sampler.h"
#include "diffusion/train.h"
#include "geodrive_version.h"
#include "geometry/util/memory.h"
#include "geometry/util/status.h"

namespace geodrive::diffusion {
// diffusion/generate_command.cc
void AddGenerateCommand(CLI::App* app, std::function<int()>* run);
}  // namespace geodrive::diffusion

int main(int argc, char** argv) {
  using namespace geodrive;
  using namespace geodrive::diffusion;
  ConfigureAllocatorForThroughput();  // geometry/memory.h
  google::InitGoogleLogging(argv[0]);
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = 1;

  CLI::App app{
      "geodrive-diffusion " GEODRIVE_VERSION
      " -- LibTorch (CPU) runtime for the GeoDrive video diffusion model: "
      "frozen "
      "CogVideoX-5B-I2V backbone plus the condition encoder.\n"
      "Run `geodrive-diffusion <command> --help` for the options of a command.",
      "geodrive-diffusion"};
  app.set_version_flag("--version",
                       std::string("geodrive-diffusion ") + GEODRIVE_VERSION);
  app.require_subcommand(1);
  int threads = 0;
  app.add_option("--threads", threads,
                 "LibTorch intra-op threads (default: OMP_NUM_THREADS, else "
                 "LibTorch's default)");

  const std::string presets = "preset: cogvideox-5b-i2v or tiny";
  std::function<int()> run;

  SampleOptions so;
  CLI::App* sample =
      app.add_subcommand("sample",
                         "Denoise from seeded noise to latents (CFG + "
                         "encoder), write latents.safetensors");
  sample->add_option("--config", so.config, presets)->capture_default_str();
  sample
      ->add_option(
          "--weights", so.weights,
          "backbone checkpoint (.safetensors or .safetensors.index.json)")
      ->required();
  sample->add_option("--branch-weights", so.branch_weights,
                     "encoder checkpoint (default: 'branch.*' tensors of "
                     "--weights, else cloned "
                     "from the backbone with zero projections)");
  sample
      ->add_option("--latents", so.latents,
                   "first-frame image latents [B, 1..F, C, H, W] (tensor "
                   "'latents' or the only "
                   "one), zero-padded to F frames")
      ->required();
  sample
      ->add_option("--cond-latents", so.cond_latents,
                   "condition-render latents [B, F, C, H, W]")
      ->required();
  sample->add_option(
      "--prompt-embeds", so.prompt_embeds,
      "safetensors with 'prompt_embeds' and 'negative_prompt_embeds' [1, L, D] "
      "(default: zero text tokens, no guidance)");
  sample
      ->add_option("--out", so.out,
                   "output latents.safetensors (tensor 'latents')")
      ->required();
  sample->add_option("--steps", so.steps, "inference steps (trailing spacing)")
      ->capture_default_str();
  sample->add_option("--seed", so.seed, "noise seed")->capture_default_str();
  sample
      ->add_option("--scheduler", so.scheduler,
                   "dpm (CogVideoXDPMScheduler) or ddim")
      ->capture_default_str();
  sample
      ->add_option("--guidance", so.guidance,
                   "classifier-free guidance scale on text")
      ->capture_default_str();
  sample->add_flag("--dynamic-cfg", so.dynamic_cfg,
                   "CogVideoX dynamic guidance schedule");
  sample
      ->add_option("--conditioning-scale", so.conditioning_scale,
                   "encoder output scale")
      ->capture_default_str();
  sample
      ->add_option("--attention-chunk-mb", so.attention_chunk_mb,
                   "max attention-score memory per chunk (MB)")
      ->capture_default_str();
  sample
      ->add_option("--ff-token-chunk", so.ff_token_chunk,
                   "feed-forward tokens per chunk")
      ->capture_default_str();
  bool no_progress = false;
  sample->add_flag("--no-progress", no_progress, "no progress bar");
  sample->callback([&] {
    run = [&] {
      so.progress = !no_progress;
      std::cout << Sample(so).Summary() << std::endl;
      return 0;
    };
  });

  InitWeightsOptions io;
  CLI::App* init = app.add_subcommand(
      "init-weights",
      "Write random test weights (backbone + encoder cloned from it)");
  init->add_option("--config", io.config, presets)->capture_default_str();
  init->add_option("--out", io.out, "output .safetensors")->required();
  init->add_option("--seed", io.seed, "initialisation seed")
      ->capture_default_str();
  init->add_flag("--nonzero-branch", io.nonzero_branch,
                 "random instead of zero encoder projections (tests)");
  bool no_branch = false;
  init->add_flag("--no-branch", no_branch, "write the backbone only");
  init->add_flag("--allow-large", io.allow_large,
                 "allow more than 1e9 parameters");
  init->callback([&] {
    run = [&] {
      io.with_branch = !no_branch;
      std::cout << InitWeightsFile(io) << std::endl;
      return 0;
    };
  });

  std::string ck_config = "cogvideox-5b-i2v", ck_weights, ck_branch;
  CLI::App* check =
      app.add_subcommand("check-weights",
                         "Report missing / unexpected / shape-mismatched names "
                         "of a checkpoint (no data read)");
  check->add_option("--config", ck_config, presets)->capture_default_str();
  check
      ->add_option("--weights", ck_weights,
                   "backbone .safetensors or .index.json")
      ->required();
  check->add_option("--branch-weights", ck_branch,
                    "encoder .safetensors or .index.json");
  check->callback([&] {
    run = [&] {
      bool ok = false;
      std::cout << CheckWeights(ck_config, ck_weights, ck_branch, &ok)
                << std::endl;
      return ok ? 0 : 2;
    };
  });

  std::string names_config = "cogvideox-5b-i2v";
  bool names_branch = false;
  CLI::App* names = app.add_subcommand("names",
                                       "Print the state-dict table (name, "
                                       "shape) a preset expects, and its size");
  names->add_option("--config", names_config, presets)->capture_default_str();
  names->add_flag("--branch", names_branch,
                  "the encoder's table instead of the backbone's");
  names->callback([&] {
    run = [&] {
      const DiTConfig cfg = ConfigPreset(names_config);
      const auto specs =
          names_branch ? BranchParamSpecs(cfg) : BackboneParamSpecs(cfg);
      for (const auto& s : specs)
        std::cout << s.name << " " << ShapeToString(s.shape) << "\n";
      std::cout << "# " << specs.size() << " tensors, " << NumElements(specs)
                << " parameters" << std::endl;
      return 0;
    };
  });

  AddTrainCommand(&app, &run);     // diffusion/train_command.cc
  AddGenerateCommand(&app, &run);  // diffusion/generate_command.cc

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "geodrive-diffusion: error: " << e.what()
              << " (see `geodrive-diffusion --help`)" << std::endl;
    return 2;
  } catch (const InputError& e) {
    std::cerr << "geodrive-diffusion: error: " << e.what() << std::endl;
    return 2;
  }
  try {
    ConfigureThreads(threads);
    return run ? run() : 1;
  } catch (const InputError& e) {
    std::cerr << "geodrive-diffusion: error: " << e.what() << std::endl;
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "geodrive-diffusion: internal error: " << e.what()
              << std::endl;
    return 1;
  }
}
