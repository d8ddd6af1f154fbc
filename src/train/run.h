#pragma once
// A whole training run (the `train` command): scenes → background sample stream → Trainer
// steps, with a progress line (loss, ETA), a JSONL log, periodic validation (loss, PSNR and
// a few PNGs of held-out target views), periodic atomic checkpoints and a model export.
//
// Layout of the run folder:
//   run.json                  options of the run (for reference)
//   log.jsonl                 one line per step (validation fields on validation steps)
//   checkpoint.safetensors    training state; `--resume` continues from it exactly
//   model.safetensors         the model alone, official key names (infer --checkpoint)
//   val/step_NNNNNN_K.png     targets (top) and renders (bottom) of validation sample K
// With several processes only rank 0 writes (validation samples are shared out, rank 0 draws
// its own); every rank reads the checkpoint on resume, so across machines the folder must be
// on a shared filesystem.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "data/scene.h"
#include "train/distributed.h"
#include "train/sample.h"
#include "train/trainer.h"

namespace ii {

struct TrainRunOptions {
  std::vector<std::filesystem::path> scene_dirs;      // each a scene or a folder of scenes
  std::vector<std::filesystem::path> val_scene_dirs;  // empty: other samples of the training scenes
  SceneOptions scene_options;
  std::filesystem::path out;
  std::string preset = "small";
  std::optional<std::filesystem::path> init;  // starting weights (3 -> 4 channels when needed)
  bool resume = false;
  int64_t steps = 1000;
  int batch = 1;  // samples per process and step
  uint64_t seed = 1024;
  SamplerOptions sampler;
  TrainerOptions trainer;
  int workers = 2;  // sample-loading threads per process
  int log_every = 10;  // progress lines when the output is not a terminal
  int val_every = 100, val_samples = 4, val_images = 2;  // 0 disables
  int save_every = 200;
  int64_t stop_after = 0;  // > 0: leave after this many steps of this invocation (checkpoint
                           // written), e.g. to fit a scheduler's time limit; --resume goes on
};

// Every scene under `dirs`: a folder that a scene reader accepts, else its sub-folders that
// one accepts (sorted by name). Errors name the folder that holds no scene.
std::vector<Scene> load_training_scenes(const std::vector<std::filesystem::path>& dirs, const SceneOptions& options);

// The model a run starts from: the preset (RGB-only for the reconstruction stage, like the
// official stage-1 model), or the weights of `init` with the 3 -> 4 channel expansion when
// the inpainting stage starts from an RGB-only model. `weight_norm`, when given, receives the
// init file's weight-norm tensors (Checkpoint::weight_norm).
Network initial_network(const TrainRunOptions& options, StateDict* weight_norm = nullptr);

// Runs (or resumes) training. Throws Error on bad input or a lost process.
void run_training(const TrainRunOptions& options, const DistributedConfig& distributed);

}  // namespace ii
