#include "train/run.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <sstream>

#include "common/error.h"
#include "common/files.h"
#include "common/stopwatch.h"
#include "io/image.h"
#include "model/checkpoint.h"
#include "tensor/image_tensor.h"
#include "train/parameters.h"

namespace ii {

namespace fs = std::filesystem;

namespace {

const char* stage_name(TrainStage s) { return s == TrainStage::Reconstruct ? "reconstruct" : "inpaint"; }

std::string duration_text(double seconds) {
  const int64_t s = static_cast<int64_t>(std::max(0.0, seconds));
  if (s >= 3600) return fmt::format("{}h{:02}m", s / 3600, (s % 3600) / 60);
  if (s >= 60) return fmt::format("{}m{:02}s", s / 60, s % 60);
  return fmt::format("{}s", s);
}

// Removes temporaries of atomic writes that a killed process left in the run folder.
void remove_stale_temporaries(const fs::path& dir) {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > 1 && name[0] == '.' && name.find(".tmp") != std::string::npos) fs::remove(entry.path(), ec);
  }
}

// Keeps the log lines of steps up to `step` (the resumed checkpoint's): later ones belong to
// the interrupted run and are recomputed.
void truncate_log(const fs::path& log, int64_t step) {
  if (!fs::exists(log)) return;
  std::ifstream in(log);
  std::string line, kept;
  while (std::getline(in, line)) {
    try {
      if (nlohmann::json::parse(line).value("step", int64_t{0}) <= step) kept += line + "\n";
    } catch (const nlohmann::json::exception&) {
      // A line cut by the interruption.
    }
  }
  write_file_atomic(log, kept);
}

// Targets (top row) over renders (bottom row), at most 4 columns, as an RGB image.
Image comparison_image(const torch::Tensor& targets, const torch::Tensor& renders) {
  const int64_t n = std::min<int64_t>(4, targets.size(0));
  const torch::Tensor top = torch::cat(targets.narrow(0, 0, n).unbind(0), 2);   // (3, H, n W)
  const torch::Tensor bottom = torch::cat(renders.narrow(0, 0, n).unbind(0), 2);
  return tensor_to_image(((torch::cat({top, bottom}, 1) + 1) * 0.5).clamp(0, 1));
}

nlohmann::json options_json(const TrainRunOptions& o, const DistributedConfig& d, const std::string& perceptual) {
  std::vector<std::string> scenes, val;
  for (const auto& p : o.scene_dirs) scenes.push_back(p.string());
  for (const auto& p : o.val_scene_dirs) val.push_back(p.string());
  const TrainerOptions& t = o.trainer;
  return {{"scenes", scenes},
          {"val_scenes", val},
          {"stage", stage_name(o.sampler.stage)},
          {"preset", o.preset},
          {"init", o.init ? o.init->string() : ""},
          {"steps", o.steps},
          {"batch_per_process", o.batch},
          {"processes", d.world_size},
          {"seed", o.seed},
          {"size", {o.sampler.width, o.sampler.height}},
          {"size_cycle", o.sampler.size_cycle},
          {"inputs", o.sampler.num_inputs},
          {"targets", o.sampler.num_targets},
          {"clip_length", o.sampler.clip_length},
          {"mask_mix", o.sampler.mask_mix},
          {"lr", {{"start", t.schedule.start_lr}, {"peak", t.schedule.peak_lr}, {"final", t.schedule.final_lr},
                  {"warmup", t.schedule.warmup_steps}}},
          {"adamw", {{"beta1", t.adamw.beta1}, {"beta2", t.adamw.beta2}, {"eps", t.adamw.eps},
                     {"weight_decay", t.adamw.weight_decay}}},
          {"clip_norm", t.clip_norm},
          {"loss", {{"mse", t.loss.mse_weight}, {"perceptual", t.loss.perceptual_weight}, {"kind", perceptual},
                    {"depth", t.loss.depth_weight}, {"own_view", t.loss.own_view_weight}}},
          {"depth_from_photos", o.sampler.depth_from_photos},
          {"precision", precision_name(t.precision)},
          {"checkpoint_blocks", t.checkpoint_blocks},
          {"device", t.device.str()}};
}

}  // namespace

std::vector<Scene> load_training_scenes(const std::vector<fs::path>& dirs, const SceneOptions& options) {
  std::vector<Scene> scenes;
  for (const fs::path& dir : dirs) {
    if (!fs::is_directory(dir)) fail("--scenes: {} is not a folder", dir.string());
    try {
      scenes.push_back(load_scene(dir, options));
      continue;
    } catch (const Error& as_scene) {
      std::vector<fs::path> subdirs;
      for (const auto& e : fs::directory_iterator(dir))
        if (e.is_directory()) subdirs.push_back(e.path());
      std::sort(subdirs.begin(), subdirs.end());
      size_t found = 0;
      for (const fs::path& sub : subdirs) {
        try {
          scenes.push_back(load_scene(sub, options));
          ++found;
        } catch (const Error& e) {
          spdlog::debug("{}: not a scene ({})", sub.string(), e.what());
        }
      }
      if (found == 0) fail("--scenes: {} is neither a scene nor a folder of scenes ({})", dir.string(), as_scene.what());
    }
  }
  return scenes;
}

Network initial_network(const TrainRunOptions& options, StateDict* weight_norm) {
  const bool inpaint = options.sampler.stage == TrainStage::Inpaint;
  if (!options.init) {
    ModelConfig config = ModelConfig::from_preset(options.preset);
    config.image_channels = inpaint ? 4 : 3;
    torch::manual_seed(options.seed);  // the same starting weights on every process
    return Network(config);
  }
  Checkpoint ck = read_checkpoint(*options.init, /*keep_weight_norm=*/weight_norm != nullptr);
  if (weight_norm) *weight_norm = std::move(ck.weight_norm);
  if (inpaint && ck.config.image_channels == 3) {
    spdlog::info("{}: RGB-only model; the mask channel's kernel starts as the mean of the RGB kernels",
                 options.init->string());
    ck.state = expand_image_channels(std::move(ck.state));
    ck.config.image_channels = 4;
  }
  return network_from_checkpoint(ck, options.init->string());
}

namespace {

struct RunFiles {
  fs::path checkpoint, model, log;
};

// The run's folder: a new run needs one without a checkpoint, --resume one with it.
RunFiles prepare_run_folder(const TrainRunOptions& options, bool lead) {
  const RunFiles files{options.out / "checkpoint.safetensors", options.out / "model.safetensors",
                       options.out / "log.jsonl"};
  if (options.resume && !fs::exists(files.checkpoint))
    fail("--resume: {} does not exist (no run to continue in {})", files.checkpoint.string(), options.out.string());
  if (!options.resume && fs::exists(files.checkpoint))
    fail("--out {} already holds a training run; pass --resume to continue it or choose another folder",
         options.out.string());
  if (lead) {
    fs::create_directories(options.out / "val");
    remove_stale_temporaries(options.out);
  }
  return files;
}

// The model to train: on resume, of the checkpoint's architecture (the weights come with
// resume_run); else a new one or --init's (its weight-norm split in `init_weight_norm`).
Network network_to_train(const TrainRunOptions& options, const RunFiles& files,
                         std::optional<SafetensorsFile>& resume_file, StateDict& init_weight_norm) {
  if (!options.resume) return initial_network(options, &init_weight_norm);
  resume_file = read_safetensors(files.checkpoint);
  return Network(training_checkpoint_config(*resume_file, files.checkpoint), /*initialise=*/false);
}

// The checkpoint's state into the trainer; returns the sampler's next sample index.
int64_t resume_run(Trainer& trainer, const TrainRunOptions& options, const RunFiles& files, const SafetensorsFile& file,
                   bool lead, int world) {
  const nlohmann::json state = trainer.load(file, files.checkpoint);
  const int64_t first_index = state.value("sampler_next_index", int64_t{0});
  // Sample indices are global, so only the global batch must stay the same.
  const int64_t saved_batch = state.value("batch_per_process", int64_t{0}) * state.value("processes", int64_t{0});
  if (lead && saved_batch != int64_t{options.batch} * world)
    spdlog::warn("resuming with a global batch of {} ({} x {} processes), the run had {}: the steps differ from an "
                 "uninterrupted run",
                 int64_t{options.batch} * world, options.batch, world, saved_batch);
  if (lead) truncate_log(files.log, trainer.steps_done());
  if (lead) spdlog::info("resumed {} at step {}", files.checkpoint.string(), trainer.steps_done());
  return first_index;
}

// The progress line on a terminal: ended before anything else is logged.
struct ProgressLine {
  bool open = false;
  void end() {
    if (open) std::fputc('\n', stderr);
    open = false;
  }
};

// Loss and PSNR over the validation samples, fixed for the whole run (each process its share),
// into a log line; rank 0 writes the images of its first val_images samples.
class Validation {
 public:
  Validation(Trainer& trainer, const TrainRunOptions& options, std::shared_ptr<ProcessGroup> group, int world,
             bool lead, ProgressLine& progress, std::vector<std::pair<int, TrainingSample>> samples)
      : trainer_(trainer), options_(options), group_(std::move(group)), world_(world), lead_(lead),
        progress_(progress), samples_(std::move(samples)) {}

  void run(int64_t step, nlohmann::json& line) {
    std::vector<double> sums(8, 0.0);  // loss, mse, perceptual, psnr, count, depth, depth count, own-view PSNR
    int images_written = 0;
    for (const auto& [index, sample] : samples_) {
      torch::Tensor renders;
      const bool image = lead_ && images_written++ < options_.val_images;
      const EvalStats e = trainer_.evaluate(sample, image ? &renders : nullptr);
      sums[0] += e.loss;
      sums[1] += e.mse;
      sums[2] += e.perceptual;
      sums[3] += e.psnr;
      sums[4] += 1;
      sums[7] += e.own_psnr;
      if (e.depth) {
        sums[5] += *e.depth;
        sums[6] += 1;
      }
      if (renders.defined())
        write_png(options_.out / "val" / fmt::format("step_{:06}_{}.png", step, index),
                  comparison_image(sample.target_images, renders));
    }
    if (group_) {
      const torch::Tensor t = torch::tensor(sums, torch::kFloat64).to(options_.trainer.device);
      group_->allreduce_mean({t}, "the validation allreduce");
      const torch::Tensor c = t.cpu() * world_;
      for (size_t k = 0; k < sums.size(); ++k) sums[k] = c[static_cast<int64_t>(k)].item<double>();
    }
    if (sums[4] == 0) return;
    const double n = sums[4];
    line["val_loss"] = sums[0] / n;
    line["val_mse"] = sums[1] / n;
    line["val_perceptual"] = sums[2] / n;
    line["val_psnr"] = sums[3] / n;
    line["val_own_psnr"] = sums[7] / n;
    if (sums[6] > 0) line["val_depth"] = sums[5] / sums[6];
    if (lead_) {
      progress_.end();
      spdlog::info("step {}: validation loss {:.4f}, PSNR {:.2f} dB{}, own views {:.2f} dB ({} samples)", step,
                   sums[0] / n, sums[3] / n, sums[6] > 0 ? fmt::format(", depth error {:.3f}", sums[5] / sums[6]) : "",
                   sums[7] / n, static_cast<int>(n));
    }
  }

 private:
  Trainer& trainer_;
  const TrainRunOptions& options_;
  std::shared_ptr<ProcessGroup> group_;
  int world_;
  bool lead_;
  ProgressLine& progress_;
  std::vector<std::pair<int, TrainingSample>> samples_;
};

// A training step's line of log.jsonl.
nlohmann::json step_line(const StepStats& s, double step_ms, double cpu_ms, double data_ms) {
  return {{"step", s.step},
          {"loss", s.loss},
          {"mse", s.mse},
          {"perceptual", s.perceptual},
          {"depth", s.depth},
          {"own_view", s.own_view},
          {"lr", s.lr},
          {"grad_norm", s.grad_norm},
          {"clipped_tensors", s.clipped_tensors},
          {"nonfinite_tensors", s.nonfinite_tensors},
          {"ms", step_ms},
          {"cpu_ms", cpu_ms},
          {"data_wait_ms", data_ms},
          {"forward_ms", s.forward_ms},
          {"render_ms", s.render_ms},
          {"backward_ms", s.backward_ms},
          {"update_ms", s.update_ms},
          {"samples_per_s", 1000.0 * s.samples / step_ms}};
}

// "step 12/300 (4%) loss ... | 840 ms/step, 1.19 samples/s | ETA 4 min".
std::string progress_text(const TrainRunOptions& options, const StepStats& s, double step_ms, double eta_s) {
  const std::string depth_text =
      (options.trainer.loss.depth_weight > 0 ? fmt::format(", depth {:.4f}", s.depth) : std::string()) +
      (options.trainer.loss.own_view_weight > 0 ? fmt::format(", own views {:.4f}", s.own_view) : std::string());
  return fmt::format("step {}/{} ({:.0f}%) loss {:.4f} (mse {:.4f}, perceptual {:.4f}{}) lr {:.2e} | {:.0f} ms/step, "
                     "{:.2f} samples/s | ETA {}",
                     s.step, options.steps, 100.0 * s.step / options.steps, s.loss, s.mse, s.perceptual, depth_text,
                     s.lr, step_ms, 1000.0 * s.samples / step_ms, duration_text(eta_s));
}

}  // namespace

void run_training(const TrainRunOptions& options, const DistributedConfig& distributed) {
  if (options.batch < 1) fail("--batch must be at least 1, got {}", options.batch);
  if (options.scene_dirs.empty()) fail("--scenes: give at least one scene folder");
  std::shared_ptr<ProcessGroup> group;
  if (distributed.enabled()) group = std::make_shared<ProcessGroup>(distributed, options.trainer.device);
  const int rank = distributed.rank, world = distributed.world_size;
  const bool lead = rank == 0;
  const RunFiles files = prepare_run_folder(options, lead);

  std::optional<SafetensorsFile> resume_file;
  StateDict init_weight_norm;
  Network network = network_to_train(options, files, resume_file, init_weight_norm);
  const ModelConfig config = network.config();
  if (options.sampler.stage == TrainStage::Inpaint && config.image_channels != 4)
    fail("the inpainting stage needs a 4-channel (RGB + mask) model, this one has {}", config.image_channels);
  TrainerOptions trainer_options = options.trainer;
  trainer_options.schedule.total_steps = options.steps;
  Trainer trainer(std::move(network), trainer_options, group);
  if (!init_weight_norm.empty()) {
    const int layers = trainer.load_weight_norm(init_weight_norm, options.init->string());
    init_weight_norm.clear();
    spdlog::debug("{}: continuing in its weight-norm split for {} layers", options.init->string(), layers);
  }
  int64_t first_index = 0;
  if (resume_file) {
    first_index = resume_run(trainer, options, files, *resume_file, lead, world);
    resume_file.reset();
  }
  if (trainer.steps_done() >= options.steps) {
    if (lead) spdlog::info("the run already has {} steps (--steps {}): nothing to do", trainer.steps_done(), options.steps);
    return;
  }
  if (lead)
    write_file_atomic(options.out / "run.json",
                      options_json(options, distributed, trainer.loss().perceptual_name()).dump(2) + "\n");

  std::vector<Scene> scenes = load_training_scenes(options.scene_dirs, options.scene_options);
  std::vector<Scene> val_scenes =
      options.val_scene_dirs.empty() ? scenes : load_training_scenes(options.val_scene_dirs, options.scene_options);
  if (lead)
    spdlog::info("{} model ({} blocks, width {}, {} image channels), {} training scene(s), stage {}, {} x {} process(es), "
                 "perceptual loss {}",
                 config.preset, config.blocks, config.embed_dim, config.image_channels, scenes.size(),
                 stage_name(options.sampler.stage), options.batch, world, trainer.loss().perceptual_name());

  // Validation samples from another random stream than training (and from other scenes when
  // --val-scenes is given). With a size cycle, each training step takes one size (every sample
  // of the global batch) and the validation samples take them in turn.
  const uint64_t val_seed = options.seed ^ 0x76616c6964617465ULL;
  std::vector<std::pair<int, TrainingSample>> val_set;
  SamplerOptions sampler = options.sampler, val_sampler = options.sampler;
  sampler.step_samples = options.batch * world;
  val_sampler.step_samples = 1;
  if (options.val_every > 0)
    for (int i = rank; i < options.val_samples; i += world)
      val_set.emplace_back(i, make_sample(val_scenes, val_sampler, val_seed, i));

  SampleStream stream(std::move(scenes), sampler, options.seed, first_index, rank, world, options.workers);
  std::ofstream log;
  if (lead) {
    log.open(files.log, std::ios::app);
    if (!log) fail_file(files.log, "cannot open for writing");
  }
  const bool tty = ::isatty(::fileno(stderr));
  const int64_t start_step = trainer.steps_done();
  Stopwatch run_clock;
  ProgressLine progress;
  Validation validation(trainer, options, group, world, lead, progress, std::move(val_set));
  double timed_ms = 0, timed_cpu_ms = 0, timed_samples = 0;  // throughput without the first (warm-up) step
  int64_t timed_steps = 0;

  // The starting point, as step 0 of the log.
  if (options.val_every > 0 && start_step == 0) {
    nlohmann::json line = {{"step", 0}};
    validation.run(0, line);
    if (lead) log << line.dump() << "\n" << std::flush;
  }
  auto save = [&](int64_t step) {
    if (!lead) return;
    const nlohmann::json state = {{"sampler_next_index", stream.next_index()},
                                  {"batch_per_process", options.batch},
                                  {"processes", world},
                                  {"seed", options.seed}};
    trainer.save(files.checkpoint, state);
    trainer.export_model(files.model, {{"step", step}, {"stage", stage_name(options.sampler.stage)}});
  };

  const int64_t end_step =
      options.stop_after > 0 ? std::min(options.steps, start_step + options.stop_after) : options.steps;
  while (trainer.steps_done() < end_step) {
    // Process CPU time (all threads, data loading included): on a shared machine a fairer
    // measure of the step's cost than wall time.
    const std::clock_t cpu_start = std::clock();
    Stopwatch data_clock;
    std::vector<TrainingSample> batch;
    for (int i = 0; i < options.batch; ++i) batch.push_back(stream.next());
    const double data_ms = data_clock.ms();
    const StepStats s = trainer.step(batch);
    const int64_t step = s.step;
    const double step_ms = data_ms + s.ms;
    const double cpu_ms = 1000.0 * static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    if (step > start_step + 1) {
      timed_ms += step_ms;
      timed_cpu_ms += cpu_ms;
      timed_samples += s.samples;
      ++timed_steps;
    }
    nlohmann::json line = step_line(s, step_ms, cpu_ms, data_ms);
    if (!options.sampler.size_cycle.empty())
      line["size"] = {batch.front().input.images.size(3), batch.front().input.images.size(2)};
    if (s.nonfinite_tensors > 0 && lead)
      spdlog::warn("step {}: {} gradient tensor(s) held NaN/Inf values (set to 0)", step, s.nonfinite_tensors);

    const bool last = step == end_step;
    if (options.val_every > 0 && (step % options.val_every == 0 || step == options.steps)) validation.run(step, line);
    if (lead) {
      log << line.dump() << "\n";
      log.flush();
    }
    if (options.save_every > 0 && (step % options.save_every == 0) && !last) save(step);

    if (lead) {
      const double done = static_cast<double>(step - start_step);
      const double eta = run_clock.ms() / 1000.0 / done * static_cast<double>(end_step - step);
      const std::string text = progress_text(options, s, step_ms, eta);
      if (tty) {
        std::fprintf(stderr, "\r%s\033[K", text.c_str());
        std::fflush(stderr);
        progress.open = true;
      } else if (options.log_every > 0 && (step % options.log_every == 0 || step == start_step + 1 || last)) {
        spdlog::info("{}", text);
      }
    }
  }
  progress.end();
  save(trainer.steps_done());
  if (lead && timed_steps > 0)
    spdlog::info("throughput: {:.0f} ms/step, {:.2f} samples/s, {:.0f} ms CPU time/step (mean of steps {}-{}, "
                 "validation excluded)",
                 timed_ms / timed_steps, 1000.0 * timed_samples / timed_ms, timed_cpu_ms / timed_steps,
                 start_step + 2, trainer.steps_done());
  if (lead)
    spdlog::info("done: {} steps in {}; checkpoint {}, model {}", trainer.steps_done() - start_step,
                 duration_text(run_clock.ms() / 1000.0), files.checkpoint.string(), files.model.string());
}

}  // namespace ii
