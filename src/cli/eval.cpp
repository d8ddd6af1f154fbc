// `instainpaint eval`: the SPIn-NeRF evaluation protocol on one scene (library: eval/protocol.h).
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>

#include "cli/commands.h"
#include "cli/edit_options.h"
#include "inpaint/lama_inpainter.h"
#include "cli/refine_options.h"
#include "cli/runtime.h"
#include "common/error.h"
#include "eval/protocol.h"

namespace ii::cli {

namespace {

struct EvalArgs {
  std::string scene_dir;
  SceneOptions scene;
  std::string out = "eval-out";
  std::string method = "model";
  std::string checkpoint, gaussians, reference;
  std::vector<std::string> context;
  int views = 4;
  int height = 512;
  int sh_degree = 3;
  bool normalized = false;
  std::string quantize = "round";
  int ring_width = 8;
  std::string lpips_vgg, lpips_alex, lpips_heads, inception;
  bool no_report = false;
  bool keep_object = false;
  EditArgs edit;
  RefineArgs refine;
  RuntimeOptions runtime;
};

std::string shown(const nlohmann::json& v, int decimals) {
  if (v.is_number()) return fmt::format("{:.{}f}", v.get<double>(), decimals);
  if (v.is_string()) return v.get<std::string>();
  return "n/a";
}

void run(const EvalArgs& a) {
  EvalOptions o;
  const Runtime runtime = apply_runtime_options(a.runtime);
  o.precision = runtime.precision;
  o.device = runtime.device;
  o.scene_dir = a.scene_dir;
  o.scene = a.scene;
  o.out = a.out;
  o.method = parse_eval_method(a.method);
  o.checkpoint = optional_path(a.checkpoint);
  o.gaussians = optional_path(a.gaussians);
  o.gaussians_normalized = a.normalized;
  if (a.normalized && !o.gaussians) fail("--normalized describes a --gaussians file: give one");
  o.reference = optional_path(a.reference);
  o.context = a.context;
  o.reference_view = a.edit.reference_view;
  o.geometry = a.edit.geometry;
  o.inpainter = inpainter_from_flag(a.edit.inpainter, "ns");
  if (a.edit.inpaint_grow >= 0) o.inpaint_grow = a.edit.inpaint_grow;
  if (a.keep_object && (!a.reference.empty() || !a.edit.view.empty()))
    fail("--keep-object evaluates a reconstruction: drop --reference, --view and --mask");
  o.keep_object = a.keep_object;
  o.scene.hold_out_whole = a.keep_object;
  if (!a.edit.view.empty()) o.edit = one_mask_request(a.edit, load_scene(a.scene_dir, o.scene), a.runtime.precision);
  o.num_views = a.views;
  o.height = a.height;
  o.sh_degree = a.sh_degree;
  o.quantize = a.quantize;
  o.ring_width = a.ring_width;
  o.lpips_vgg = optional_path(a.lpips_vgg);
  o.lpips_alex = optional_path(a.lpips_alex);
  o.lpips_heads_dir = optional_path(a.lpips_heads);
  o.inception = optional_path(a.inception);
  o.write_report = !a.no_report;
  const RefineOptions refine = refine_options(a.refine);
  if (refine_requested(refine) && (o.method != EvalMethod::model || o.gaussians))
    fail("--refine refines the network's prediction: use it with --method model and without --gaussians");
  if (refine_requested(refine))
    o.after_prediction = [&refine, out = o.out](const Scene& scene, const Prediction& p, const SceneInputOptions& input,
                                   GaussianSet g, nlohmann::json& report) {
      report["refine"] = nlohmann::json::object();
      GaussianSet refined = refine_prediction(scene, p, input, g, refine, report["refine"]);
      write_loss_chart(out, report["refine"]);
      return refined;
    };
  const nlohmann::json m = run_evaluation(o);

  const nlohmann::json& mean = m["mean"];
  fmt::print("{} ({}, task {}): {} test views\n", m["scene"].get<std::string>(), m["method"].get<std::string>(),
             m["task"].get<std::string>(), m["views"].size());
  fmt::print("  PSNR {}  SSIM {}  masked PSNR {}  masked SSIM {}\n", shown(mean.value("psnr", nlohmann::json()), 2),
             shown(mean.value("ssim", nlohmann::json()), 4), shown(mean.value("masked_psnr", nlohmann::json()), 2),
             shown(mean.value("masked_ssim", nlohmann::json()), 4));
  fmt::print("  LPIPS {}  masked LPIPS {}  FID {}  KID {}  C-FID {}  C-KID {}\n",
             shown(mean.value("lpips", nlohmann::json()), 4), shown(mean.value("masked_lpips", nlohmann::json()), 4),
             shown(m["set"].value("fid", nlohmann::json()), 2), shown(m["set"].value("kid", nlohmann::json()), 5),
             shown(m["set"].value("c_fid", nlohmann::json()), 2), shown(m["set"].value("c_kid", nlohmann::json()), 5));
  const nlohmann::json& rw = m["region_and_whole"];
  if (rw["psnr"].contains("region_minus_whole"))
    fmt::print("  region against the whole image: PSNR {} against {} ({:+.2f} dB){}\n", shown(rw["psnr"]["region"], 2),
               shown(rw["psnr"]["whole"], 2), rw["psnr"]["region_minus_whole"].get<double>(),
               rw.contains("uncovered") ? fmt::format("; uncovered region pixels {} in {} views",
                                                      rw["uncovered"]["pixels"].get<int64_t>(),
                                                      rw["uncovered"]["views"].get<int>())
                                        : "");
  if (m["prediction"].contains("own_views"))
    fmt::print("  the context views' own Gaussians at their cameras: PSNR {} outside the masks (mean of {})\n",
               shown(m["prediction"]["own_views"]["mean_psnr_outside_mask"], 2),
               m["prediction"]["own_views"]["views"].size());
  if (m["prediction"].contains("reference_protocol"))
    fmt::print("  reference: the object-free test view {} (its photo), not scored\n",
               m["prediction"]["reference_protocol"]["view"].get<std::string>());
  if (!m["unavailable"].empty()) {
    std::string keys;
    for (const auto& [k, reason] : m["unavailable"].items()) keys += (keys.empty() ? "" : ", ") + k;
    fmt::print("  unavailable: {} (reasons in metrics.json)\n", keys);
  }
  const nlohmann::json& t = m["timings"];
  fmt::print("  on {}: {:.0f} ms of computation (inputs to the device, network, renders, metrics), {:.0f} ms in all "
             "with reading and writing files\n",
             m["device"].get<std::string>(), t["compute_ms"].get<double>(), t["total_ms"].get<double>());
  fmt::print("wrote {}/metrics.json{}\n", a.out, a.no_report ? "" : fmt::format(", {}/report.html", a.out));
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  auto* cmd = app.add_subcommand(
      "eval", "Evaluate on a SPIn-NeRF scene's object-free test views (PSNR, SSIM, LPIPS, FID, KID)");
  add_scene_options(cmd, a->scene_dir, a->scene);
  cmd->add_option("--out", a->out, "Output folder")->capture_default_str();
  cmd->add_option("--method", a->method,
                  "model: the Gaussians of --checkpoint or --gaussians; telea: each test view's mask filled by "
                  "OpenCV Telea from its own ground truth; mean-fill: filled with the mean colour of a ring around "
                  "the mask. Insertion scenes (synth --task insert): floor: the view with nothing inserted "
                  "(original/); sticker: that view with the --reference's edit region pasted flat at the background "
                  "depth")
      ->check(CLI::IsMember({"model", "telea", "mean-fill", "floor", "sticker"}))
      ->capture_default_str();
  cmd->add_option("--checkpoint", a->checkpoint,
                  kCheckpointHelp);
  cmd->add_option("--gaussians", a->gaussians,
                  "Splat file (PLY, compressed PLY, SPZ, SOG) to evaluate instead of running a model, in the scene's "
                  "frame (its cameras': as `infer` and `fill` write it, and 3DGS trainers)")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--normalized", a->normalized,
                "The --gaussians file is in the pose-normalised frame (infer --normalized, and infer before "
                "it wrote the scene's frame)");
  cmd->add_option("--reference", a->reference,
                  "The reference view with the object painted out by a 2D inpainter (default: painted by --inpainter)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--context", a->context,
                  "Context views by name, reference first (default: automatic). An object-free test view as the "
                  "first is the ground-truth reference: its photo the reference, its test mask the region, and it "
                  "is not scored (the paper's protocol)")
      ->delimiter(',');
  add_reference_options(cmd, a->edit);
  add_edit_options(cmd, a->edit);
  add_refine_options(cmd, a->refine);
  cmd->add_flag("--keep-object", a->keep_object,
                "Evaluate a reconstruction of the scene as captured (no masks, the reference's own photo; views held "
                "out by --hold-out-every are compared whole): how well the model and --refine reconstruct");
  cmd->add_option("--views", a->views, "Number of context views when chosen automatically")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  cmd->add_option("--height", a->height, "Working height: inputs and test views are resized to it (official: 512)")
      ->capture_default_str()
      ->check(CLI::Range(8, 4096));
  cmd->add_option("--sh-degree", a->sh_degree, "Highest SH degree used from a --gaussians PLY")
      ->capture_default_str()
      ->check(CLI::Range(0, 3));
  cmd->add_option("--quantize", a->quantize,
                  "Predictions to 8 bits before the metrics: round, truncate (as the official metric_output PNGs), "
                  "none")
      ->check(CLI::IsMember({"round", "truncate", "none"}))
      ->capture_default_str();
  cmd->add_option("--ring-width", a->ring_width, "mean-fill: width in pixels of the ring around the mask")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--lpips-vgg", a->lpips_vgg,
                  "torchvision VGG16 ImageNet weights (vgg16-397923af.pth) for LPIPS; default $INSTAINPAINT_LPIPS_VGG");
  cmd->add_option("--lpips-alex", a->lpips_alex,
                  "torchvision AlexNet weights (alexnet-owt-7be5be79.pth), adds lpips_alex; default "
                  "$INSTAINPAINT_LPIPS_ALEX");
  cmd->add_option("--lpips-heads", a->lpips_heads, "Folder of the LPIPS heads (default: shared/data/lpips)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--inception", a->inception,
                  "pytorch-fid Inception weights (pt_inception-2015-12-05-6726825d.pth) for FID/KID/C-FID/C-KID; "
                  "default $INSTAINPAINT_FID_INCEPTION");
  cmd->add_flag("--no-report", a->no_report, "Skip report.html and the contact sheets");
  add_runtime_options(cmd, a->runtime);
  cmd->footer(
      "Test views are those of images_K/test_label/ (SPIn-NeRF layout); each is resized to --height rows,\n"
      "centre-cropped to a multiple of 8, compared with the prediction quantised to 8 bits.\n"
      "Writes OUT/metrics.json (per view and mean psnr, ssim, masked_psnr, masked_ssim, box_*, lpips,\n"
      "masked_lpips; fid, kid, c_fid, c_kid; unavailable metrics with the reason; timings),\n"
      "OUT/report.html, OUT/renders/<view>.png and OUT/sheets/<view>.png.\n"
      "Examples:\n"
      "  instainpaint eval --scene spinnerf/book --checkpoint release.pth --reference book_inpainted.png \\\n"
      "      --context 20220811_094244,20220811_094233,20220811_094251,20220811_094300 --out eval/book\n"
      "  # the true photo as the reference: an object-free test view first (20220819_104221 is not scored)\n"
      "  instainpaint eval --scene spinnerf/1 --context 20220819_104221,20220819_104429,20220819_104503 --out eval/gt\n"
      "  # a fill made with that view as its reference, scored on the other test views\n"
      "  instainpaint eval --scene spinnerf/1 --gaussians filled.ply --reference-view 20220819_104221 --out eval/fill");
  cmd->callback([a] { run(*a); });
}

}  // namespace ii::cli
