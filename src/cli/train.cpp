// `instainpaint train`: both training stages (reconstruction pre-training, masked inpainting
// fine-tuning) on one process or several (data-parallel). A thin layer over train/run.h.
#include <spdlog/spdlog.h>

#include <cstdlib>
#include <fstream>
#include <iterator>

#include "cli/commands.h"
#include "cli/size_option.h"
#include "common/error.h"
#include "model/config.h"
#include "model/device.h"
#include "train/launcher.h"
#include "train/run.h"

namespace ii::cli {

namespace fs = std::filesystem;

namespace {

struct TrainArgs {
  std::vector<std::string> scenes, val_scenes;
  SceneOptions scene;
  std::string out;
  std::string stage = "inpaint";
  std::string preset = "small";
  std::string init;
  bool resume = false;
  int64_t steps = 1000;
  int batch = 1;
  int width = 256, height = 256;
  int inputs = 4, targets = 8, clip = 15, max_masks = 4;
  std::vector<double> mask_mix{1, 2, 1};
  std::vector<std::string> size_cycle;
  double lr = 8e-5, lr_start = 1e-10, lr_final = 1e-6;
  int64_t warmup = -1;
  double weight_decay = 0.05, clip_norm = 1.0;
  double mse_weight = 1.0, perceptual_weight = 0.5, depth_weight = 0.0;
  std::string perceptual = "auto", lpips_vgg, lpips_heads;
  std::string precision = "fp32", device = "cpu";
  bool checkpoint_blocks = false;
  bool depth_from_photos = false;
  double own_view_weight = 0.0;
  int threads = 0, workers = 2;
  uint64_t seed = 1024;
  int val_every = 100, val_samples = 4, val_images = 2, save_every = 200, log_every = 10;
  int64_t stop_after = 0;
  int nproc = 1, master_port = 0, dist_timeout = 600;
};

// This process's command line without --nproc (for the copies it starts).
std::vector<std::string> arguments_without_nproc() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  const std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::string> args;
  for (size_t start = 0; start < all.size();) {
    const size_t end = all.find('\0', start);
    args.push_back(all.substr(start, end - start));
    start = end == std::string::npos ? all.size() : end + 1;
  }
  std::vector<std::string> out;
  for (size_t i = 1; i < args.size(); ++i) {
    if (args[i] == "--nproc" || args[i] == "--master-port") {
      ++i;
      continue;
    }
    if (args[i].rfind("--nproc=", 0) == 0 || args[i].rfind("--master-port=", 0) == 0) continue;
    out.push_back(args[i]);
  }
  return out;
}

TrainRunOptions run_options(const TrainArgs& a) {
  TrainRunOptions o;
  for (const auto& s : a.scenes) o.scene_dirs.emplace_back(s);
  for (const auto& s : a.val_scenes) o.val_scene_dirs.emplace_back(s);
  o.scene_options = a.scene;
  o.out = a.out;
  o.preset = a.preset;
  if (!a.init.empty()) o.init = fs::path(a.init);
  o.resume = a.resume;
  o.steps = a.steps;
  o.batch = a.batch;
  o.seed = a.seed;
  o.sampler.stage = a.stage == "reconstruct" ? TrainStage::Reconstruct : TrainStage::Inpaint;
  o.sampler.width = a.width;
  o.sampler.height = a.height;
  for (const std::string& text : a.size_cycle) {
    const InputSize size = parse_size(text, "--size-cycle");
    o.sampler.size_cycle.emplace_back(size.width, size.height);
  }
  o.sampler.num_inputs = a.inputs;
  o.sampler.num_targets = a.targets;
  o.sampler.depth_from_photos = a.depth_from_photos;
  o.sampler.clip_length = a.clip;
  o.sampler.max_mask_count = a.max_masks;
  if (a.mask_mix.size() != 3) fail("--mask-mix needs three weights (instance, random, 3dconsistent)");
  o.sampler.mask_mix = {a.mask_mix[0], a.mask_mix[1], a.mask_mix[2]};
  check_sampler_options(o.sampler);

  TrainerOptions& t = o.trainer;
  t.schedule.peak_lr = a.lr;
  t.schedule.start_lr = a.lr_start;
  t.schedule.final_lr = a.lr_final;
  t.schedule.warmup_steps = a.warmup >= 0 ? a.warmup : std::min<int64_t>(200, a.steps / 10);
  t.schedule.total_steps = a.steps;
  t.schedule.validate();
  t.adamw.weight_decay = a.weight_decay;
  t.clip_norm = a.clip_norm;
  t.loss.mse_weight = a.mse_weight;
  t.loss.perceptual_weight = a.perceptual_weight;
  t.loss.perceptual = a.perceptual;
  t.loss.depth_weight = a.depth_weight;
  t.loss.own_view_weight = a.own_view_weight;
  if (!a.lpips_vgg.empty()) t.loss.lpips_backbone = fs::path(a.lpips_vgg);
  if (!a.lpips_heads.empty()) t.loss.lpips_heads = fs::path(a.lpips_heads);
  t.precision = a.precision == "bf16" ? Precision::BFloat16 : Precision::Float32;
  t.checkpoint_blocks = a.checkpoint_blocks;
  o.workers = a.workers;
  o.val_every = a.val_every;
  o.val_samples = a.val_samples;
  o.val_images = a.val_images;
  o.save_every = a.save_every;
  o.log_every = a.log_every;
  o.stop_after = a.stop_after;
  return o;
}

void run(const TrainArgs& a) {
  DistributedConfig dist = DistributedConfig::from_environment();
  if (a.nproc > 1 && !dist.enabled()) {
    // The launcher: N copies of this command, each one rank.
    LaunchOptions launch;
    launch.processes = a.nproc;
    launch.master_port = a.master_port;
    const int code = run_local_processes(fs::read_symlink("/proc/self/exe"), arguments_without_nproc(), launch);
    if (code != 0) fail("training with {} processes failed (see the messages above)", a.nproc);
    return;
  }
  dist.timeout = std::chrono::seconds(a.dist_timeout);
  // One voice: the other ranks report only warnings and errors.
  if (dist.rank != 0) spdlog::set_level(spdlog::level::warn);
  TrainRunOptions o = run_options(a);
  o.trainer.device = rank_device(a.device, dist);
  set_cpu_threads(a.threads);
  run_training(o, dist);
}

}  // namespace

void add_train_command(CLI::App& app) {
  auto args = std::make_shared<TrainArgs>();
  CLI::App* cmd = app.add_subcommand(
      "train",
      "Train or fine-tune the model. Stage 'reconstruct' pre-trains an RGB-only model to\n"
      "reproduce held-out views from 4 input views; stage 'inpaint' trains the masked model\n"
      "(optionally starting from a stage-1 model: the mask channel is added). Loss per target\n"
      "view: MSE + 0.5 x perceptual (LPIPS-VGG when its backbone is supplied, else 1 - SSIM);\n"
      "AdamW (0.9, 0.95, weight decay 0.05), linear warm-up then cosine decay, per-tensor\n"
      "gradient clipping at 1. Writes RUN/log.jsonl, RUN/checkpoint.safetensors (resumable),\n"
      "RUN/model.safetensors (for infer --checkpoint) and validation images in RUN/val/.\n"
      "Several processes: --nproc N here, or start one per rank with the torchrun variables\n"
      "MASTER_ADDR, MASTER_PORT, RANK, WORLD_SIZE, LOCAL_RANK (any launcher or scheduler).");
  cmd->add_option("--scenes", args->scenes, "Training scene folders, each a scene or a folder of scenes (comma-separated)")
      ->required()
      ->delimiter(',')
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--val-scenes", args->val_scenes,
                  "Held-out scenes for validation (default: other samples of the training scenes)")
      ->delimiter(',')
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--format", args->scene.format, "Scene format")
      ->check(CLI::IsMember({"auto", "llff", "nerfstudio", "colmap"}))
      ->capture_default_str();
  cmd->add_option("--images", args->scene.image_folder, "Image sub-folder to read (e.g. images_4)");
  cmd->add_option("--out", args->out, "Run folder (created; must not hold a run unless --resume)")->required();
  cmd->add_option("--stage", args->stage, "reconstruct (stage 1, RGB-only model) or inpaint (stage 2)")
      ->check(CLI::IsMember({"reconstruct", "inpaint"}))
      ->capture_default_str();
  cmd->add_option("--preset", args->preset, fmt::format("Model size when not --init ({})", ModelConfig::preset_names()))
      ->capture_default_str();
  cmd->add_option("--init", args->init, "Start from these weights (.pth, safetensors or a training checkpoint)")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--resume", args->resume, "Continue the run in --out from its checkpoint (same losses as without the break)");
  cmd->add_option("--steps", args->steps, "Total optimisation steps of the run")->capture_default_str();
  cmd->add_option("--batch", args->batch, "Samples per process and step")->capture_default_str();
  cmd->add_option("--width", args->width, "Training image width")->capture_default_str();
  cmd->add_option("--height", args->height, "Training image height")->capture_default_str();
  cmd->add_option("--size-cycle", args->size_cycle,
                  "Working sizes taken in turn, one per step, in place of --width/--height: N or WxH each,\n"
                  "repeated for weight (128,128,128,256: every fourth step at 256 x 256); validation\n"
                  "samples take them in turn too")
      ->delimiter(',');
  cmd->add_option("--inputs", args->inputs, "Input views per sample (reference first)")->capture_default_str();
  cmd->add_option("--targets", args->targets, "Supervised target views per sample")->capture_default_str();
  cmd->add_option("--clip", args->clip, "Clip length in frames that inputs and targets come from")->capture_default_str();
  cmd->add_option("--mask-mix", args->mask_mix, "Mask mode weights instance,random,3dconsistent")
      ->delimiter(',')
      ->expected(3)
      ->capture_default_str();
  cmd->add_option("--max-masks", args->max_masks, "Most masks (objects, rectangles, ellipses) per sample")
      ->capture_default_str();
  cmd->add_option("--lr", args->lr, "Peak learning rate (end of warm-up)")->capture_default_str();
  cmd->add_option("--lr-start", args->lr_start, "Learning rate at the first warm-up step")->capture_default_str();
  cmd->add_option("--lr-final", args->lr_final, "Learning rate at the end of the cosine decay")->capture_default_str();
  cmd->add_option("--warmup", args->warmup, "Warm-up steps (default: min(200, steps / 10))");
  cmd->add_option("--weight-decay", args->weight_decay, "AdamW weight decay")->capture_default_str();
  cmd->add_option("--clip-norm", args->clip_norm, "Per-tensor gradient norm limit")->capture_default_str();
  cmd->add_option("--mse-weight", args->mse_weight, "Weight of the MSE term")->capture_default_str();
  cmd->add_option("--perceptual-weight", args->perceptual_weight, "Weight of the perceptual term")->capture_default_str();
  cmd->add_option("--depth-weight", args->depth_weight,
                  "Weight of a log-depth L1 loss on the inputs' predicted depth, for scenes with depth maps\n"
                  "(synthetic: depth/, depth_clean/); not in the official recipe")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  cmd->add_flag("--depth-from-photos", args->depth_from_photos,
                "With --depth-weight: scenes without depth maps (real captures) are supervised at points\n"
                "triangulated from their photos with their cameras (sparse; once per scene)");
  cmd->add_option("--own-view-weight", args->own_view_weight,
                  "Weight of an MSE term for each input's own Gaussians at its own camera against its image\n"
                  "outside its mask (eval's own-views check); not in the official recipe")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  cmd->add_option("--perceptual", args->perceptual,
                  "Perceptual term: auto (LPIPS-VGG when its backbone is available, else 1 - SSIM), lpips, ssim, none")
      ->check(CLI::IsMember({"auto", "lpips", "ssim", "none"}))
      ->capture_default_str();
  cmd->add_option("--lpips-vgg", args->lpips_vgg,
                  "torchvision VGG16 weights for LPIPS (vgg16-397923af.pth; default $INSTAINPAINT_LPIPS_VGG)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--lpips-heads", args->lpips_heads, "LPIPS linear heads vgg.safetensors (default: found in shared/)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--precision", args->precision, "Network forward precision (bf16 = autocast-like; losses stay fp32)")
      ->check(CLI::IsMember({"fp32", "bf16"}))
      ->capture_default_str();
  cmd->add_flag("--checkpoint-blocks", args->checkpoint_blocks,
                "Recompute transformer blocks in the backward pass (less memory, ~1/3 more compute)");
  cmd->add_option("--device", args->device, "cpu, or cuda (GPU LOCAL_RANK; needs a CUDA build)")
      ->check(CLI::IsMember({"cpu", "cuda"}))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "CPU threads per process (0 = $OMP_NUM_THREADS or all cores)")
      ->capture_default_str();
  cmd->add_option("--workers", args->workers, "Sample-loading threads per process")->capture_default_str();
  cmd->add_option("--seed", args->seed, "Seed of the data order and the initial weights")->capture_default_str();
  cmd->add_option("--val-every", args->val_every, "Validate every K steps and at the end (0 = never)")->capture_default_str();
  cmd->add_option("--val-samples", args->val_samples, "Validation samples")->capture_default_str();
  cmd->add_option("--val-images", args->val_images, "Validation samples written as PNGs")->capture_default_str();
  cmd->add_option("--save-every", args->save_every, "Checkpoint every K steps and at the end (0 = end only)")
      ->capture_default_str();
  cmd->add_option("--stop-after", args->stop_after,
                  "Leave after N steps of this invocation, with a checkpoint (e.g. a scheduler's time limit); "
                  "--resume continues")
      ->capture_default_str();
  cmd->add_option("--log-every", args->log_every, "Progress line every K steps when not on a terminal")
      ->capture_default_str();
  cmd->add_option("--nproc", args->nproc, "Start N local processes (data-parallel, Gloo over loopback)")
      ->capture_default_str();
  cmd->add_option("--master-port", args->master_port, "Rendezvous port for --nproc (0 = any free port)");
  cmd->add_option("--dist-timeout", args->dist_timeout,
                  "Seconds a process waits for the others (rendezvous and each collective) before failing")
      ->capture_default_str();
  cmd->callback([args] { run(*args); });
}

}  // namespace ii::cli
