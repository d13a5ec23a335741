// `geodrive-diffusion`: the LibTorch diffusion runtime (CogVideoX-5B-I2V
// backbone + GeoDrive condition encoder). Subcommands: sample, init-weights,
// check-weights, names, train (diffusion/train_command.cc), generate
// (diffusion/generate_command.cc), registered in the registry both binaries
// share (apps/cli/cli.h). Exit codes: 0 ok, 1 internal failure, 2 bad
// arguments or bad input.

#include <glog/logging.h>

#include <iostream>
#include <memory>

#include "apps/cli/cli.h"
#include "diffusion/config.h"
#include "diffusion/runtime_cli.h"
#include "diffusion/sampler.h"
#include "diffusion/train.h"
#include "geodrive_version.h"
#include "geometry/util/memory.h"
#include "geometry/util/output_file.h"

namespace geodrive::diffusion {
namespace {

const char kPresets[] = "preset: tiny, tiny-49 or cogvideox-5b-i2v";

CommandRunner SetupSample(CLI::App& cmd) {
  struct Args {
    SampleOptions so;
    RuntimeArgs runtime;
    bool no_progress = false;
  };
  auto a = std::make_shared<Args>();
  SampleOptions& so = a->so;
  cmd.add_option("--config", so.config, kPresets)->capture_default_str();
  cmd.add_option(
         "--weights", so.weights,
         "backbone checkpoint (.safetensors or .safetensors.index.json)")
      ->required();
  cmd.add_option("--branch-weights", so.branch_weights,
                 "encoder checkpoint (default: 'branch.*' tensors of "
                 "--weights, else cloned "
                 "from the backbone with zero projections)");
  cmd.add_option("--latents", so.latents,
                 "first-frame image latents [B, 1..F, C, H, W] (tensor "
                 "'latents' or the only "
                 "one), zero-padded to F frames")
      ->required();
  cmd.add_option("--cond-latents", so.cond_latents,
                 "condition-render latents [B, F, C, H, W]")
      ->required();
  cmd.add_option(
      "--prompt-embeds", so.prompt_embeds,
      "safetensors with 'prompt_embeds' and 'negative_prompt_embeds' [1, L, D] "
      "(default: zero text tokens, no guidance)");
  cmd.add_option("--out", so.out,
                 "output latents.safetensors (tensor 'latents')")
      ->required();
  cmd.add_option("--steps", so.steps, "inference steps (trailing spacing)")
      ->capture_default_str();
  cmd.add_option("--seed", so.seed, "noise seed")->capture_default_str();
  cmd.add_option("--scheduler", so.scheduler,
                 "dpm (CogVideoXDPMScheduler) or ddim")
      ->capture_default_str();
  cmd.add_option("--guidance", so.guidance,
                 "classifier-free guidance scale on text")
      ->capture_default_str();
  cmd.add_flag("--dynamic-cfg", so.dynamic_cfg,
               "CogVideoX dynamic guidance schedule");
  cmd.add_option("--conditioning-scale", so.conditioning_scale,
                 "encoder output scale")
      ->capture_default_str();
  cmd.add_option("--attention-chunk-mb", so.attention_chunk_mb,
                 "max attention-score memory per chunk (MB)")
      ->capture_default_str();
  cmd.add_option("--ff-token-chunk", so.ff_token_chunk,
                 "feed-forward tokens per chunk")
      ->capture_default_str();
  cmd.add_flag("--no-progress", a->no_progress, "no progress bar");
  AddRuntimeOptions(cmd, &a->runtime, kRuntimeAttention | kRuntimeOffload);
  return [a] {
    a->so.progress = !a->no_progress;
    a->so.runtime = a->runtime.Parse();
    a->so.attention = a->runtime.Attention();
    CheckOutputIsNotInput(a->so.out,
                          {a->so.weights, a->so.branch_weights, a->so.latents,
                           a->so.cond_latents, a->so.prompt_embeds});
    std::cout << Sample(a->so).BriefReport() << std::endl;
    return 0;
  };
}

CommandRunner SetupInitWeights(CLI::App& cmd) {
  struct Args {
    InitWeightsOptions io;
    bool no_branch = false;
  };
  auto a = std::make_shared<Args>();
  InitWeightsOptions& io = a->io;
  cmd.add_option("--config", io.config, kPresets)->capture_default_str();
  cmd.add_option("--out", io.out, "output .safetensors")->required();
  cmd.add_option("--seed", io.seed, "initialisation seed")
      ->capture_default_str();
  cmd.add_flag("--nonzero-branch", io.nonzero_branch,
               "random instead of zero encoder projections (tests)");
  cmd.add_flag("--no-branch", a->no_branch, "write the backbone only");
  cmd.add_flag("--allow-large", io.allow_large,
               "allow more than 1e9 parameters");
  cmd.add_flag("--vae", io.vae,
               "write the VAE the preset pairs with (random test weights, "
               "diffusers names) instead of the transformer");
  return [a] {
    a->io.with_branch = !a->no_branch;
    std::cout << InitWeightsFile(a->io) << std::endl;
    return 0;
  };
}

CommandRunner SetupCheckWeights(CLI::App& cmd) {
  struct Args {
    std::string config = "cogvideox-5b-i2v", weights, branch;
    RuntimeArgs runtime;
  };
  auto a = std::make_shared<Args>();
  cmd.add_option("--config", a->config, kPresets)->capture_default_str();
  cmd.add_option("--weights", a->weights,
                 "backbone .safetensors or .index.json")
      ->required();
  cmd.add_option("--branch-weights", a->branch,
                 "encoder .safetensors or .index.json");
  AddRuntimeOptions(cmd, &a->runtime, kRuntimeOffload);
  return [a] {
    bool ok = false;
    std::cout << CheckWeights(a->config, a->weights, a->branch, &ok,
                              a->runtime.Parse())
              << std::endl;
    return ok ? 0 : 2;
  };
}

CommandRunner SetupNames(CLI::App& cmd) {
  struct Args {
    std::string config = "cogvideox-5b-i2v";
    bool branch = false;
  };
  auto a = std::make_shared<Args>();
  cmd.add_option("--config", a->config, kPresets)->capture_default_str();
  cmd.add_flag("--branch", a->branch,
               "the encoder's table instead of the backbone's");
  return [a] {
    const DiTConfig cfg = ConfigPreset(a->config);
    const auto specs =
        a->branch ? BranchParamSpecs(cfg) : BackboneParamSpecs(cfg);
    for (const auto& s : specs)
      std::cout << s.name << " " << ShapeToString(s.shape) << "\n";
    std::cout << "# " << specs.size() << " tensors, " << NumElements(specs)
              << " parameters" << std::endl;
    return 0;
  };
}

}  // namespace

GEODRIVE_REGISTER_COMMAND(
    sample,
    "sample",
    "Denoise from seeded noise to latents (CFG + encoder), write "
    "latents.safetensors",
    SetupSample);
GEODRIVE_REGISTER_COMMAND(
    init_weights,
    "init-weights",
    "Write random test weights (backbone + encoder cloned from it)",
    SetupInitWeights);
GEODRIVE_REGISTER_COMMAND(check_weights,
                          "check-weights",
                          "Report missing / unexpected / shape-mismatched "
                          "names of a checkpoint (no data read)",
                          SetupCheckWeights);
GEODRIVE_REGISTER_COMMAND(names,
                          "names",
                          "Print the state-dict table (name, shape) a preset "
                          "expects, and its size",
                          SetupNames);

}  // namespace geodrive::diffusion

int main(int argc, char** argv) {
  using namespace geodrive;
  ConfigureAllocatorForThroughput();  // geometry/util/memory.h
  google::InitGoogleLogging(argv[0]);
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = 1;
  static int threads = 0;
  CliProgram program;
  program.name = "geodrive-diffusion";
  program.description =
      "geodrive-diffusion " GEODRIVE_VERSION
      " -- LibTorch runtime (CPU, or CUDA with a CUDA LibTorch: --device) for "
      "the GeoDrive video diffusion model: "
      "frozen CogVideoX-5B-I2V backbone plus the condition encoder.\n"
      "Run `geodrive-diffusion <command> --help` for the options of a "
      "command.";
  program.version = std::string("geodrive-diffusion ") + GEODRIVE_VERSION;
  program.add_global_options = [](CLI::App& app) {
    app.add_option("--threads", threads,
                   "LibTorch intra-op threads (default: OMP_NUM_THREADS, else "
                   "LibTorch's default)");
  };
  program.before_run = [] { diffusion::ConfigureThreads(threads); };
  return RunCommandLine(program, argc, argv);
}
