#include "web/server.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <fstream>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <regex>
#include <set>
#include <thread>

#include <nlohmann/json.hpp>

#include "common/compute_thread.h"
#include "common/error.h"
#include "common/files.h"
#include "common/parallel.h"
#include "common/stage_times.h"
#include "common/stopwatch.h"
#include "camera/trajectory.h"
#include "data/inpaint2d.h"
#include "data/photo_points.h"
#include "data/preprocess.h"
#include "data/scene_cameras.h"
#include "edit/scene_masks.h"
#include "eval/protocol.h"
#include "fill/fill.h"
#include "fill/region.h"
#include "gaussians/gaussians.h"
#include "io/image.h"
#include "io/ply.h"
#include "io/splat_file.h"
#include "io/video.h"
#include "model/default_model.h"
#include "models/cache.h"
#include "models/download.h"
#include "refine/reconstruct.h"
#include "refine/refine.h"
#include "render/frames.h"
#include "render/rasterizer.h"
#include "tensor/image_tensor.h"
#include "web/assets.h"
#include "web/page_selection.h"

// Last: it includes <resolv.h>, whose `_res` macro breaks Eigen headers included after it.
#include <httplib.h>

namespace ii {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// A request the server refuses: the status and the message the client sees.
struct Refusal {
  int status;
  std::string message;
};

void reply(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

void refuse(httplib::Response& res, const Refusal& r) { reply(res, r.status, {{"error", r.message}}); }

// Whether an Accept-Encoding header lists gzip (as httplib decides it, without weights).
bool accepts_gzip(std::string accept_encoding) {
  std::transform(accept_encoding.begin(), accept_encoding.end(), accept_encoding.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return accept_encoding.find("gzip") != std::string::npos;
}

// The host name of a Host header or of an origin's authority ("[::1]:8080" -> "[::1]").
std::string host_name(std::string_view authority) {
  if (!authority.empty() && authority.front() == '[') return std::string(authority.substr(0, authority.find(']') + 1));
  return std::string(authority.substr(0, authority.find(':')));
}

// Any website open in the user's browser can send requests to a server on loopback, and with
// DNS rebinding read the answers. Served are only requests addressed to this server by one of
// its names (Host: loopback names and --host), and requests that change anything only from
// the server's own page (a browser's Origin equals the Host it sent to).
std::optional<Refusal> foreign_request(const httplib::Request& req, const std::string& bound_host) {
  const std::string host = req.get_header_value("Host");
  const std::string name = host_name(host);
  if (name != "localhost" && name != "127.0.0.1" && name != "[::1]" && name != bound_host &&
      name != "[" + bound_host + "]")
    return Refusal{403, fmt::format("Host '{}' is not a name of this server (open it as http://127.0.0.1:<port>/ "
                                    "or by the --host it was started with)",
                                    host)};
  if (req.method != "GET" && req.method != "HEAD" && req.has_header("Origin")) {
    const std::string origin = req.get_header_value("Origin");
    const std::string_view scheme = "http://";
    if (origin.rfind(scheme, 0) != 0 || origin.substr(scheme.size()) != host)
      return Refusal{403, fmt::format("a request from another website ({}) may not change anything here", origin)};
  }
  return std::nullopt;
}

constexpr const char* token_header = "X-Instainpaint-Token";

// 128 random bits as hex: what a local program or a website would have to guess.
std::string random_token() {
  std::random_device device;
  std::string token;
  for (int i = 0; i < 4; ++i) token += fmt::format("{:08x}", static_cast<uint32_t>(device()));
  return token;
}

// Cookies are per host name, not per port: each server's cookie carries its port.
std::string token_cookie(int port) { return fmt::format("instainpaint-token-{}", port); }

std::string cookie_value(const httplib::Request& req, const std::string& name) {
  const std::string cookies = req.get_header_value("Cookie");
  for (size_t at = 0; at < cookies.size();) {
    size_t end = cookies.find(';', at);
    if (end == std::string::npos) end = cookies.size();
    std::string_view pair(cookies.data() + at, end - at);
    while (!pair.empty() && pair.front() == ' ') pair.remove_prefix(1);
    if (pair.size() > name.size() && pair.substr(0, name.size()) == name && pair[name.size()] == '=')
      return std::string(pair.substr(name.size() + 1));
    at = end + 1;
  }
  return {};
}

// Equal without an early exit, so that the time taken says nothing about how much of a guess
// was right (the length is no secret).
bool same_secret(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

// The token comes as ?token= (the address `serve` prints; the answer then sets the cookie, so
// that the page's own requests carry it), as the cookie, or as a header (scripts).
std::optional<Refusal> missing_token(const httplib::Request& req, httplib::Response& res, const std::string& token,
                                     int port) {
  if (token.empty()) return std::nullopt;
  const std::string cookie = token_cookie(port);
  if (req.has_param("token") && same_secret(req.get_param_value("token"), token)) {
    res.set_header("Set-Cookie", fmt::format("{}={}; Path=/; HttpOnly; SameSite=Strict", cookie, token));
    return std::nullopt;
  }
  const std::string from_cookie = cookie_value(req, cookie);
  if (same_secret(from_cookie, token) || same_secret(req.get_header_value(token_header), token)) return std::nullopt;
  const bool given = req.has_param("token") || req.has_header(token_header) || !from_cookie.empty();
  return Refusal{403, fmt::format("{} token: open the address that `instainpaint serve` printed at start "
                                  "(http://...:{}/?token=...), or send the token as the {} header",
                                  given ? "wrong" : "missing", port, token_header)};
}

const char* image_type(std::string_view bytes) {
  if (bytes.size() >= 8 && bytes.substr(0, 8) == std::string_view("\x89PNG\r\n\x1a\n", 8)) return "png";
  if (bytes.size() >= 3 && bytes.substr(0, 3) == std::string_view("\xFF\xD8\xFF", 3)) return "jpg";
  return nullptr;
}

// Streams a file (PLYs may be hundreds of MB); ?download=1 makes it an attachment.
void send_file(const httplib::Request& req, httplib::Response& res, const fs::path& path, const std::string& type) {
  if (req.has_param("download"))
    res.set_header("Content-Disposition", "attachment; filename=\"" + path.filename().string() + "\"");
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) return refuse(res, {404, "not found"});
  auto in = std::make_shared<std::ifstream>(path, std::ios::binary);
  if (!*in) return refuse(res, {404, "not found"});
  res.set_content_provider(static_cast<size_t>(size), type,
                           [in](size_t offset, size_t length, httplib::DataSink& sink) {
                             std::vector<char> buffer(std::min<size_t>(length, 1 << 20));
                             in->seekg(static_cast<std::streamoff>(offset));
                             in->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
                             const auto got = in->gcount();
                             if (got <= 0) return false;
                             sink.write(buffer.data(), static_cast<size_t>(got));
                             return true;
                           });
}

// The last job's state, as GET /api/job returns it.
struct Job {
  int id = 0;
  std::string kind;             // "masks", "edit", "video", "eval", "reconstruct" or "train"
  std::string state = "idle";   // "running", "done", "failed"
  std::string stage;
  double progress = 0;          // 0..1
  std::string error;
  json result = json::object();
  double seconds = 0;
  json stages = json::array();  // StageTimes::to_json of the finished job: where its time went

  json to_json() const {
    return {{"id", id},         {"kind", kind},     {"state", state},   {"stage", stage}, {"progress", progress},
            {"error", error},   {"result", result}, {"seconds", seconds}, {"stages", stages}};
  }
};

// What a job request asks for, checked before any work starts.
struct JobRequest {
  std::string kind;  // "masks", "edit", "video", "eval", "reconstruct", "train"
  // masks, edit:
  int view = -1;
  EditMode mode = EditMode::Remove;
  Image region;                    // the uploaded mask, checked against the view
  std::optional<Image> reference;  // the uploaded inpainted reference (fill: of the painted view)
  RefineOptions refine = refine_setting("0");  // train: how long
  // video, eval: the PLY, one the server serves; fill: the splats to fill (a served file, or a
  // job's standard PLY), and the region: a box, or `region` drawn on `camera`
  fs::path ply;
  std::optional<OrientedBox> box;
  std::optional<Camera> camera;
  std::vector<Click> clicks;  // fill: in place of `region`, clicks on the object on `camera`
  std::vector<Click> not_clicks;  // with a segmenter: points on `camera` that are not the object
  Inpainter inpainter;  // fill without a reference: the server's (serve --inpainter), else the one asked for
  bool slower_model = false;  // edit: with the released checkpoint offered beside the built-in model
  bool selected = false;      // masks, edit: the region is the click or box tool's outline (kSelectionInpaintGrow)
};

// The inpainter as the page sees it: its file by name only (the server's folders stay its own).
json served_inpainter(const Inpainter& inpainter) {
  json out = inpainter.describe();
  if (out.contains("file")) out["file"] = fs::path(out["file"].get<std::string>()).filename().string();
  return out;
}

// The form's `refine`: fast, balanced, best, a time up to 20 minutes or up to 5000 steps.
std::optional<Refusal> parse_refine(const httplib::Request& req, RefineOptions& refine) {
  if (!req.has_file("refine")) return std::nullopt;
  try {
    refine = refine_setting(req.get_file_value("refine").content);
  } catch (const Error&) {
    refine.steps = -1;
  }
  if (refine.steps < 0 || refine.steps > 5000 || refine.time_budget_s > 1200)
    return Refusal{400, "refine must be fast, balanced or best, a time up to 20m, or a number of steps up to 5000"};
  return std::nullopt;
}

// Whether the form carries a file in `field` with something in it (the page sends an empty one
// when nothing was chosen).
bool uploaded(const httplib::Request& req, const char* field) {
  return req.has_file(field) && !req.get_file_value(field).content.empty();
}

using SizeCheck = std::function<std::optional<std::string>(const ImageInfo&)>;

// Refuses an upload of more than 4 times the pixels of the `width` x `height` picture `what` names.
SizeCheck at_most_4_times(int width, int height, const std::string& what) {
  return [width, height, what](const ImageInfo& info) -> std::optional<std::string> {
    if (static_cast<int64_t>(info.width) * info.height <= 4 * static_cast<int64_t>(width) * height) return std::nullopt;
    return fmt::format("{}x{} pixels, more than this server decodes for {} ({}x{}: at most 4 times its pixels)",
                       info.width, info.height, what, width, height);
  };
}

// An uploaded image (form field `field`): PNG or JPEG by its first bytes, kept in `dir` under the
// field's name, its header checked by `refuse_size` (a reason, or none) before `decode` reads it,
// so that a few kilobytes claiming gigabytes of pixels are never decoded; errors name the field,
// not the file.
std::optional<Refusal> read_upload(const httplib::Request& req, const char* field, const fs::path& dir,
                                   const SizeCheck& refuse_size,
                                   const std::function<Image(const fs::path&)>& decode, Image& into) {
  const std::string& bytes = req.get_file_value(field).content;
  const char* type = image_type(bytes);
  if (!type) return Refusal{415, fmt::format("{}: not a PNG or JPEG image", field)};
  fs::create_directories(dir);
  const fs::path file = dir / (std::string(field) + "." + type);
  write_file_atomic(file, bytes);
  try {
    if (const std::optional<std::string> reason = refuse_size(probe_image(file)))
      return Refusal{400, fmt::format("{}: {}", field, *reason)};
    into = decode(file);
  } catch (const std::exception& e) {
    std::string what = e.what();
    if (what.rfind(file.string() + ": ", 0) == 0) what.erase(0, file.string().size() + 2);
    return Refusal{400, fmt::format("{}: {}", field, what)};
  }
  return std::nullopt;
}

// The form's `camera`: a camera list of one (render --cameras' JSON, camera/trajectory.h), read by
// that list's reader from `dir`.
std::optional<Refusal> read_page_camera(const httplib::Request& req, const fs::path& dir, Camera& camera) {
  fs::create_directories(dir);
  write_file_atomic(dir / "camera.json", req.get_file_value("camera").content);
  try {
    const std::vector<NamedCamera> cameras = read_camera_json(dir / "camera.json");
    if (cameras.size() != 1) return Refusal{400, "camera: give one camera"};
    camera = cameras[0].camera;
  } catch (const Error& e) {
    std::string what = e.what();
    const std::string file = (dir / "camera.json").string() + ": ";
    if (what.rfind(file, 0) == 0) what.erase(0, file.size());
    return Refusal{400, "camera: " + what};
  }
  const int w = camera.K.width, h = camera.K.height;
  if (w > 8192 || h > 8192) return Refusal{400, fmt::format("camera: {}x{} pixels, at most 8192 each way", w, h)};
  return std::nullopt;
}

// The form's `clicks`: "x,y;x,y..." in the camera's pixels, at most 32.
constexpr size_t kMaxClicks = 32;
std::optional<Refusal> read_clicks(const httplib::Request& req, std::vector<Click>& clicks,
                                   const std::string& field = "clicks") {
  const std::string text = req.get_file_value(field).content;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(';', start), text.size());
    try {
      clicks.push_back(parse_click(text.substr(start, end - start), field));
    } catch (const Error& e) {
      return Refusal{400, e.what()};
    }
    if (clicks.size() > kMaxClicks) return Refusal{400, fmt::format("{}: at most {}", field, kMaxClicks)};
    start = end + 1;
  }
  return std::nullopt;
}

const char* content_type_of(const fs::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".png") return "image/png";
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".mp4") return "video/mp4";
  if (ext == ".json") return "application/json";
  return "application/octet-stream";
}

// What the page loads is ready before the job is done: SuperSplat's compressed PLY, quick to
// make and to send, served from memory until its file is written. SPZ's compression was most
// of an edit (1.36 s of a 2.5 s edit at 512 high on an H100 machine); the standard PLY is 4x
// the bytes (95 MB against 23 MB for the statue's 1.39 M Gaussians at 512 high: 85 ms written,
// 107 ms sent over loopback on the H100 machine). Every file (that one too, and the downloads,
// standard PLY and SPZ) is written after the answer; requests for the downloads wait.
constexpr const char* kPageSplats = "gaussians.compressed.ply";
constexpr const char* kDownloadSplats[] = {"gaussians.ply", "gaussians.spz"};

// Files a job leaves to write after its answer, in order, by group ("masks", "splats"): a
// request for a file waits for its group alone.
using BehindSteps = std::vector<std::pair<std::string, std::function<void()>>>;

// The file group a job's file belongs to (BehindSteps).
std::string file_group(const std::string& relative) { return relative.rfind("masks/", 0) == 0 ? "masks" : "splats"; }

// The result's URLs of a job's splats ("splats": the page's).
json splat_urls(int id) {
  json result = {{"splats", fmt::format("/api/jobs/{}/{}", id, kPageSplats)}};
  for (const char* name : kDownloadSplats)
    result[fs::path(name).extension().string().substr(1)] = fmt::format("/api/jobs/{}/{}", id, name);
  return result;
}

void write_splat_files(const fs::path& dir, const std::string& page_bytes, const SplatCloud& cloud,
                       StageTimes& stages) {
  stages.time(std::string("write ") + kPageSplats, [&] { write_file_atomic(dir / kPageSplats, page_bytes); }, true);
  for (const char* name : kDownloadSplats)
    stages.time(std::string("write ") + name, [&] { write_splats(dir / name, cloud); }, /*behind=*/true);
}

// The URL of the splats an export (video, eval) is asked for: the form's or the query's `ply`.
std::string exported_url(const httplib::Request& req) {
  return req.has_file("ply") ? req.get_file_value("ply").content : req.get_param_value("ply");
}

// Sends bytes held in memory (shared with whoever keeps them); ?download=1 as send_file.
void send_bytes(const httplib::Request& req, httplib::Response& res, std::shared_ptr<const std::string> bytes,
                const std::string& name) {
  if (req.has_param("download")) res.set_header("Content-Disposition", "attachment; filename=\"" + name + "\"");
  const size_t size = bytes->size();
  res.set_content_provider(size, "application/octet-stream",
                           [bytes](size_t offset, size_t length, httplib::DataSink& sink) {
                             sink.write(bytes->data() + offset, std::min<size_t>(length, 1 << 20));
                             return true;
                           });
}

}  // namespace

struct WebServer::State {
  ServeOptions options;
  // Every job's and click's LibTorch work (ServeOptions::compute, else one of the server's own).
  std::shared_ptr<ComputeThread> compute;
  const Predictor* predictor = nullptr;
  std::optional<Scene> scene;
  PoseNormalization normalization;
  httplib::Server http;
  fs::path out;  // canonical
  std::string token;
  int port = 0;

  // Guards job, next_id, queued, worker_busy, stopping, files_pending, files_writer,
  // page_splats and the view PNG cache.
  std::mutex mutex;
  std::condition_variable changed;  // the job's state, the queue or files_pending changed
  std::mutex sog_mutex;  // one SOG made at a time (downloads)
  Job job;
  int next_id = 1;
  // One worker thread runs every job, started with the first: LibTorch keeps per-thread state
  // on a GPU (cuDNN's attention plans among it) that a thread per job rebuilt each time, about
  // 50 ms of every edit on an H100.
  std::thread worker;
  std::optional<std::pair<JobRequest, fs::path>> queued;
  bool worker_busy = false, stopping = false;
  // The file groups of each job still being written, after its answer, by files_writer.
  std::map<int, std::set<std::string>> files_pending;
  std::thread files_writer;
  // The page's splats of the newest jobs, by job: sent from memory (written behind the answer).
  std::map<int, std::shared_ptr<const std::string>> page_splats;
  PreparedViewCache views;  // the edits' context views at the working size, read once
  // The scene's reconstruction with the object kept (the first job when it opens without
  // splats), on the rasterizer's device, pose-normalised frame: later edits' depth comes from it.
  std::optional<GaussianSet> reconstruction;
  // Its depth at each view's working camera (the edits' masks start from the marked view's):
  // drawn once per view (statue at 256 rows: 0.12 s that a second edit or preview of the view,
  // the page's usual course, does not wait for).
  std::mutex reconstruction_depth_mutex;
  std::map<size_t, torch::Tensor> reconstruction_depth;
  torch::Tensor reconstruction_depth_in(size_t view, const PreprocessOptions& working);

  // The page's click tools: the splats they select in, the reconstruction's points.
  PageSelection selection;
  json select(const httplib::Request& req);
  // The request's `ply`: splats this server serves.
  fs::path selection_splats_file(const httplib::Request& req);
  json select_on_view(const httplib::Request& req, const std::vector<Click>& clicks, const std::vector<Click>& not_clicks,
                      const std::optional<ViewBox>& box);

  // The released checkpoint a CPU page offers as a slower, better Run (ServeOptions::slower_checkpoint),
  // read at its first use.
  std::mutex slower_mutex;
  std::unique_ptr<Predictor> slower;
  const Predictor& slower_predictor();

  ~State() { stop_worker(); }
  void worker_loop();
  void stop_worker();

  json info() const;
  json networks() const;
  std::optional<Refusal> parse_edit(const httplib::Request& req, JobRequest& edit, const fs::path& dir) const;
  // The file behind a URL of splats this server serves (a PLY given at start, a job's splats;
  // with standard_ply, that job's standard PLY whichever of its files was named), or empty.
  fs::path splats_of_url(const std::string& url, bool standard_ply) const;
  std::optional<Refusal> parse_export(const httplib::Request& req, JobRequest& job) const;
  std::optional<Refusal> parse_train(const httplib::Request& req, JobRequest& job) const;
  std::optional<Refusal> parse_fill(const httplib::Request& req, JobRequest& fill, const fs::path& dir) const;
  // A file a job wrote, from its URL path below /api/jobs/ ("3/gaussians.ply"); empty when
  // it is not one (or leads outside `out`).
  fs::path job_file(const std::string& id, const std::string& relative) const;
  void run_job(JobRequest request, fs::path dir);
  // run_edit and run_reconstruction record their stages in `stages` and may leave download
  // files to write in `behind` (run after the job is done).
  json run_edit(const JobRequest& edit, const fs::path& dir, int id,
                const std::function<void(const std::string&, double)>& stage, StageTimes& stages,
                BehindSteps& behind);
  json run_video(const JobRequest& job, const fs::path& dir, int id,
                 const std::function<void(const std::string&, double)>& stage);
  json run_eval(const JobRequest& job, const fs::path& dir, int id);
  // 3DGS of the whole capture (refine/reconstruct.h) at the page's working height.
  json run_train(const JobRequest& job, const fs::path& dir, int id,
                 const std::function<void(const std::string&, double)>& stage, StageTimes& stages, BehindSteps& behind);
  json run_reconstruction(const fs::path& dir, int id, const std::function<void(const std::string&, double)>& stage,
                          StageTimes& stages, BehindSteps& behind);
  json run_fill(const JobRequest& fill, const fs::path& dir, int id,
                const std::function<void(const std::string&, double)>& stage, StageTimes& stages, BehindSteps& behind);
  // Splats (in the scene's frame) as the page's file now, the downloads in `behind`.
  json write_cloud_of(std::shared_ptr<const SplatCloud> cloud, const fs::path& dir, int id, StageTimes& stages,
                      BehindSteps& behind);
  // The prediction's Gaussians as splats: the page's file now, the files in `behind`.
  json write_splats_of(const GaussianSet& gaussians, const fs::path& dir, int id, StageTimes& stages,
                       BehindSteps& behind);
  // Starts job `id` on the worker thread; the caller holds `mutex` and checked that none runs.
  void launch_locked(const JobRequest& request, int id, const fs::path& dir);
  fs::path cached_view_file(int index, bool mask);
  void update(const std::function<void(Job&)>& change) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      change(job);
    }
    changed.notify_all();
  }
  // The current job once it is job `id` and no longer running, waiting at most `limit`.
  json wait_for_job(int id, std::chrono::milliseconds limit) {
    std::unique_lock<std::mutex> lock(mutex);
    changed.wait_for(lock, limit, [&] { return job.id == id && job.state != "running"; });
    return job.to_json();
  }
  // Waits until job `id`'s files of `group` are written (at once when none are pending).
  void wait_for_files(int id, const std::string& group) {
    std::unique_lock<std::mutex> lock(mutex);
    changed.wait(lock, [&] {
      const auto pending = files_pending.find(id);
      return pending == files_pending.end() || pending->second.count(group) == 0;
    });
  }
  // Starts writing a finished job's files behind its answer (its groups are pending already).
  void write_files_behind(int id, BehindSteps steps, std::shared_ptr<StageTimes> stages);
};

// Which networks the page runs, where each came from, and for each one absent the command that
// brings it (the page says so).
json WebServer::State::networks() const {
  json n = json::object();
  // The file by name only (the server's folders stay its own), and whether the cache holds it.
  const auto served_file = [](const fs::path& file) {
    return json{{"file", file.filename().string()}, {"from", cached_model_of_file(file) ? "the cache" : "a path"}};
  };
  if (options.segmenter) {
    n["segmenter"] = served_file(options.segmenter->file());
    n["segmenter"]["network"] = options.segmenter->description();
  } else {
    n["segmenter"] = {{"missing", true}, {"get", get_command("mobile-sam")}, {"instead", "colour growth"}};
  }
  if (options.inpainter.learned)
    n["inpainter"] = served_inpainter(options.inpainter);
  else
    n["inpainter"] = {{"missing", true}, {"get", get_command("big-lama")}, {"instead", options.inpainter.name()}};
  if (predictor) {
    const bool builtin = predictor->model_name() == kDefaultModelName;
    n["model"] = builtin ? json{{"file", predictor->model_name()}, {"from", "built in"}} : served_file(predictor->model_name());
    if (options.slower_checkpoint) {
      // About 11 s an edit at 256 rows on 2 cores (its tokens grow with the square of the height).
      const double rows = options.height / 256.0, cores = std::max(1u, std::thread::hardware_concurrency());
      n["released"] = {{"offered", true},
                       {"seconds_estimate", std::max(1L, std::lround(11.0 * rows * rows * 2.0 / cores))},
                       {"file", options.slower_checkpoint->filename().string()}};
    }
    else if (builtin)
      n["released"] = {{"missing", true}, {"get", get_command("instainpaint")}};
  }
  return n;
}

json WebServer::State::info() const {
  json views = json::array();
  if (scene)
    for (size_t i = 0; i < scene->views.size(); ++i) {
      const View& v = scene->views[i];
      const Camera& c = v.camera;  // the scene's frame, as the splats are written
      json c2w = json::array();
      for (int r = 0; r < 4; ++r)
        for (int k = 0; k < 4; ++k) c2w.push_back(c.c2w(r, k));
      views.push_back({{"index", i}, {"name", v.name}, {"width", c.K.width}, {"height", c.K.height},
                       {"fx", c.K.fx}, {"fy", c.K.fy}, {"cx", c.K.cx}, {"cy", c.K.cy}, {"c2w", c2w},
                       {"image", fmt::format("/api/views/{}/image", i)},
                       {"mask", v.mask_path || v.mask_from_alpha ? json(fmt::format("/api/views/{}/mask", i))
                                                                 : json()}});
    }
  json plys = json::array();
  for (size_t i = 0; i < options.plys.size(); ++i)
    plys.push_back({{"index", i}, {"name", options.plys[i].filename().string()},
                    {"url", fmt::format("/api/plys/{}", i)}});
  return {{"scene", scene ? json{{"root", scene->root.string()},
                                 {"format", scene->format},
                                 {"views", views},
                                 {"test_views", scene->test_views.size()}}
                          : json()},
          {"plys", plys},
          {"editing", scene.has_value() && predictor != nullptr},
          {"filling", predictor != nullptr},
          {"model", predictor ? predictor->describe() : json()},
          {"segmenter", options.segmenter ? json{{"network", options.segmenter->description()},
                                                 {"file", options.segmenter->file().filename().string()},
                                                 {"views_encoded", selection.views_encoded()}}
                                          : json()},
          {"inpainter", served_inpainter(options.inpainter)},
          {"networks", networks()},
          {"working_height", options.height}};
}

fs::path WebServer::State::cached_view_file(int index, bool mask) {
  const View& view = scene->views.at(static_cast<size_t>(index));
  const fs::path file = out / "cache" / fmt::format("{}-{}.png", mask ? "mask" : "view", index);
  std::lock_guard<std::mutex> lock(mutex);
  if (!fs::exists(file)) {
    fs::create_directories(file.parent_path());
    if (mask) {
      const std::optional<Image> m = load_view_mask(view);
      if (!m) return {};
      write_png(file, *m);
    } else {
      write_png(file, load_view_image(view));
    }
  }
  return file;
}

fs::path WebServer::State::job_file(const std::string& id, const std::string& relative) const {
  const fs::path file = out / "jobs" / id / relative;
  std::error_code ec;
  const fs::path real = fs::canonical(file, ec);
  if (ec || fs::is_symlink(file) || real.string().rfind(out.string() + "/", 0) != 0 || !fs::is_regular_file(real))
    return {};
  return real;
}

fs::path WebServer::State::splats_of_url(const std::string& url, bool standard_ply) const {
  std::smatch m;
  static const std::regex served(R"(/api/plys/(\d{1,6}))"),
      job_splats(R"(/api/jobs/(\d{1,8})/(gaussians\.(ply|spz|compressed\.ply)))");
  if (std::regex_match(url, m, served) && std::stoul(m[1]) < options.plys.size()) return options.plys[std::stoul(m[1])];
  if (std::regex_match(url, m, job_splats)) return job_file(m[1], standard_ply ? "gaussians.ply" : m[2].str());
  return {};
}

std::optional<Refusal> WebServer::State::parse_export(const httplib::Request& req, JobRequest& job) const {
  const std::string url = exported_url(req);
  job.ply = splats_of_url(url, /*standard_ply=*/false);
  if (job.ply.empty()) return Refusal{400, fmt::format("ply must be the URL of a PLY this server serves, not '{}'", url)};
  if (job.kind == "eval" && scene->test_views.empty())
    return Refusal{400, "the scene has no test views to evaluate on (SPIn-NeRF test_label/, or serve --hold-out-every N)"};
  return std::nullopt;
}

// The form's `length`: fast, balanced, best, a time up to 20 minutes or up to 30,000 steps.
std::optional<Refusal> WebServer::State::parse_train(const httplib::Request& req, JobRequest& job) const {
  const std::string text = req.has_file("length") ? req.get_file_value("length").content
                           : req.has_param("length") ? req.get_param_value("length")
                                                     : "fast";
  try {
    job.refine = refine_setting(text);
  } catch (const Error& e) {
    return Refusal{400, e.what()};
  }
  if (job.refine.time_budget_s > 1200 || job.refine.steps > 30000 || !refine_requested(job.refine))
    return Refusal{400, fmt::format("length '{}': the page trains for at most 20 minutes or 30,000 steps", text)};
  return std::nullopt;
}

std::optional<Refusal> WebServer::State::parse_edit(const httplib::Request& req, JobRequest& edit,
                                                    const fs::path& dir) const {
  const bool run_network = edit.kind == "edit";
  if (!req.is_multipart_form_data()) return Refusal{400, "send multipart/form-data with view and mask"};
  if (!req.has_file("view")) return Refusal{400, "no view given"};
  const std::string name = req.get_file_value("view").content;
  for (size_t i = 0; i < scene->views.size(); ++i)
    if (scene->views[i].name == name) edit.view = static_cast<int>(i);
  if (edit.view < 0) return Refusal{400, fmt::format("no view '{}' in the scene", name)};
  const View& view = scene->views[static_cast<size_t>(edit.view)];

  if (req.has_file("mode")) {
    const std::string mode = req.get_file_value("mode").content;
    if (mode != "remove" && mode != "insert") return Refusal{400, "mode must be remove or insert"};
    edit.mode = parse_edit_mode(mode);
  }
  if (auto r = parse_refine(req, edit.refine)) return r;
  if (req.has_file("selected")) {
    const std::string selected = req.get_file_value("selected").content;
    if (selected != "0" && selected != "1") return Refusal{400, "selected must be 0 or 1"};
    edit.selected = selected == "1";
  }
  if (run_network && req.has_file("model")) {
    const std::string model = req.get_file_value("model").content;
    if (model == "released") {
      if (!options.slower_checkpoint)
        return Refusal{400, "this server offers no second model (the released checkpoint: instainpaint models get "
                            "instainpaint, then serve again)"};
      edit.slower_model = true;
    } else if (model != "default") {
      return Refusal{400, "model must be default or released"};
    }
  }

  // Uploaded images: PNG or JPEG, kept in the job's folder under fixed names and decoded now
  // (a broken file is the request's fault, not the job's); errors name the field, not the file.
  // The header is read first: a few kilobytes of PNG can claim gigabytes of pixels, so nothing
  // larger than 4 times the view is decoded.
  const SizeCheck at_most_4_views = at_most_4_times(view.camera.K.width, view.camera.K.height, "view " + view.name);
  if (!req.has_file("mask")) return Refusal{400, "no mask given (a PNG of the view's size, white = region)"};
  if (auto r = read_upload(req, "mask", dir, at_most_4_views, [&](const fs::path& f) { return read_region_mask(f, view); },
                           edit.region))
    return r;
  if (run_network && uploaded(req, "reference")) {
    edit.reference.emplace();
    if (auto r = read_upload(req, "reference", dir, at_most_4_views, read_image_rgb, *edit.reference)) return r;
  }
  if (run_network && edit.mode == EditMode::Insert && !edit.reference)
    return Refusal{400, "insert needs a reference: the view's photo with the new object painted in"};
  return std::nullopt;
}

std::optional<Refusal> WebServer::State::parse_fill(const httplib::Request& req, JobRequest& fill,
                                                    const fs::path& dir) const {
  if (!req.is_multipart_form_data()) return Refusal{400, "send multipart/form-data with ply and a box or a camera and mask"};
  // The splats on screen: a served file, or a job's result read from its standard PLY (exact).
  const std::string url = exported_url(req);
  fill.ply = splats_of_url(url, /*standard_ply=*/true);
  if (fill.ply.empty()) return Refusal{400, fmt::format("ply must be the URL of splats this server serves, not '{}'", url)};
  if (auto r = parse_refine(req, fill.refine)) return r;
  fill.inpainter = options.inpainter;
  if (req.has_file("inpainter")) {
    const std::string name = req.get_file_value("inpainter").content;
    if (name == "lama") {
      if (!options.inpainter.learned)
        return Refusal{400, "inpainter: lama needs LaMa in the cache (instainpaint models get big-lama, then serve "
                            "again) or serve --inpainter FILE"};
      fill.inpainter = options.inpainter;
    } else {
      try {
        fill.inpainter = parse_inpainter(name);
      } catch (const Error& e) {
        return Refusal{400, std::string("inpainter: ") + e.what()};
      }
    }
  }
  const bool reference = uploaded(req, "reference");
  if (req.has_file("box")) {
    if (reference)
      return Refusal{400, "reference: only with a painted region (camera and mask); a box's reference view is the fill's choice"};
    try {
      fill.box = parse_box(req.get_file_value("box").content);
    } catch (const Error& e) {
      return Refusal{400, std::string(e.what()).replace(0, 5, "box")};  // "--box" is the CLI's name
    }
    return std::nullopt;
  }
  if (!req.has_file("camera") || !(req.has_file("mask") || req.has_file("clicks")))
    return Refusal{400, "give the region: box (cx,cy,cz,sx,sy,sz[,rx,ry,rz]), or camera and mask or clicks"};
  fill.camera.emplace();
  if (auto r = read_page_camera(req, dir, *fill.camera)) return r;
  const int w = fill.camera->K.width, h = fill.camera->K.height;
  const auto camera_sized = [w, h](const ImageInfo& info) -> std::optional<std::string> {
    if (info.width == w && info.height == h) return std::nullopt;
    return fmt::format("{}x{} pixels, but the camera is {}x{}", info.width, info.height, w, h);
  };
  if (req.has_file("clicks")) {
    if (auto r = read_clicks(req, fill.clicks)) return r;
    if (req.has_file("not_clicks") && !req.get_file_value("not_clicks").content.empty())
      if (auto r = read_clicks(req, fill.not_clicks, "not_clicks")) return r;
  } else if (auto r = read_upload(req, "mask", dir, camera_sized, read_mask, fill.region)) {
    return r;
  }
  if (!reference) return std::nullopt;
  // The view on screen painted out by a 2D inpainter: the page saves that view at the camera's
  // size; as the CLI's fill, the view's working size and the official evaluation's crop of it
  // (904x512 of a 1008x567 view) are taken too.
  fill.reference.emplace();
  if (auto r = read_upload(req, "reference", dir, at_most_4_times(w, h, "the view on screen"), read_image_rgb,
                           *fill.reference))
    return r;
  WorkingSize view;
  view.width = view.resized_width = w;
  view.height = view.resized_height = h;
  if (view_picture_at_working_size(*fill.reference, w, h, view, PreprocessOptions().patch)) return std::nullopt;
  return Refusal{400, fmt::format("reference: {}x{} pixels, but the view on screen is {}x{} (save view and mask, "
                                  "paint the view, keep the camera still)",
                                  fill.reference->width, fill.reference->height, w, h)};
}

json WebServer::State::run_fill(const JobRequest& fill, const fs::path& dir, int id,
                                const std::function<void(const std::string&, double)>& stage, StageTimes& stages,
                                BehindSteps& behind) {
  stage("reading the splats", 0.05);
  const SplatCloud cloud = stages.time("read splats", [&] { return read_splats(fill.ply); });
  FillOptions o;
  o.scene_name = fill.ply.filename().string();
  o.box = fill.box;
  if (scene)
    for (const View& v : scene->views) o.cameras.push_back({v.name, v.camera});
  if (fill.camera) {
    o.cameras.push_back({"page view", *fill.camera});
    o.stroke_view = "page view";
    if (fill.clicks.empty()) o.stroke = fill.region;
    o.clicks = fill.clicks;
    o.not_clicks = fill.not_clicks;
    o.segmenter = options.segmenter;  // the page's selection is the segmenter's outline: the fill takes the same
    o.reference_image = fill.reference;
  }
  o.camera_options.height = options.height;
  o.camera_options.views = options.views;
  o.inpainter = fill.inpainter;
  if (refine_requested(fill.refine)) {
    o.refine = fill.refine;
    int shown = -1;
    o.refine->progress = [&](const RefineProgress& p) {
      if (static_cast<int>(p.fraction * 100) == shown) return;
      shown = static_cast<int>(p.fraction * 100);
      stage(fmt::format("refining the new splats: {:.0f} s left", p.eta_s), 0.4 + 0.5 * p.fraction);
    };
  }
  stage("removing the region and filling the hole", 0.1);
  FillResult r = fill_splats(cloud, o, *predictor);
  stages.merge(r.stages);
  stages.restart_lap();
  json report = r.report();
  write_file_atomic(dir / "fill.json", report.dump(2) + "\n");
  stage("writing the splats", 0.95);
  json result = write_cloud_of(std::make_shared<const SplatCloud>(std::move(r.splats)), dir, id, stages, behind);
  result["fill"] = {{"removed", r.removed}, {"added", r.added}, {"cameras", report["cameras"]["how"]},
                    {"reference", report["cameras"]["reference"]}, {"inpainter", r.inpainter},
                    {"report", fmt::format("/api/jobs/{}/fill.json", id)}};
  return result;
}

json WebServer::State::run_edit(const JobRequest& edit, const fs::path& dir, int id,
                                const std::function<void(const std::string&, double)>& stage, StageTimes& stages,
                                BehindSteps& behind) {
  const View& view = scene->views[static_cast<size_t>(edit.view)];
  const Predictor* model = predictor;
  if (edit.slower_model) {
    stage("reading the released checkpoint", 0.02);
    model = &stages.time("read the released checkpoint", [&]() -> const Predictor& { return slower_predictor(); });
  }
  SceneInputOptions input;
  input.preprocess.height = options.height;
  input.num_views = options.views;
  input.view_cache = &views;
  input.geometry = options.geometry;
  input.inpainter = options.inpainter;
  // The click or box tool's outline lies on the object's edge: its rim is painted over too.
  if (edit.selected) input.inpaint_grow = kSelectionInpaintGrow;
  if (edit.mode == EditMode::Insert) input.geometry = input.geometry.for_insertion();
  OneMask request;
  request.view = view.name;
  request.region = edit.region;
  request.propagation.mode = edit.mode;
  // The marked view's depth from the scene's reconstruction (made when the page opened): drawn
  // at its working camera, in place of a second network call (one network call per edit).
  if (reconstruction) {
    request.working_depth = stages.time("masks: depth from the scene's reconstruction",
                                        [&] { return reconstruction_depth_in(static_cast<size_t>(edit.view), input.preprocess); });
    request.working_depth_source = "the scene's reconstruction";
  }
  stage("propagating the mask to every view", 0.05);
  // Without an uploaded reference the view is inpainted classically, beside the propagation
  // (its mask is the region itself): 130 ms at 512 high that the edit no longer waits for. A
  // learned inpainter paints on this thread when it is waited for: LibTorch's work on a second
  // thread would slow both (common/compute_thread.h).
  std::future<Image> inpainted;
  const bool learned = input.inpainter.learned != nullptr;
  if (!edit.reference && edit.kind == "edit")
    inpainted = std::async(learned ? std::launch::deferred : std::launch::async,
                           [this, &view, &edit, &stages, learned, options = input] {
      return stages.time(fmt::format("inpaint reference ({})", options.inpainter.name()),
                         [&] { return painted_reference(*scene, view.name, edit.region, options); }, !learned);
    });
  const SceneMasks masks = masks_from_one(
      *scene, request, [model]() -> const Predictor& { return *model; }, input, &stages);
  // The masks' PNGs: for a preview now, for an edit behind its answer (the page draws the
  // splats first; requests for the masks wait until they are written).
  json mask_files = json::object();
  auto mask_pngs = std::make_shared<std::vector<std::pair<fs::path, Image>>>();
  for (size_t i = 0; i < scene->views.size(); ++i) {
    const auto m = masks.masks.find(scene->views[i].name);
    if (m == masks.masks.end()) continue;
    mask_pngs->emplace_back(dir / "masks" / fmt::format("{}.png", i), m->second);
    mask_files[scene->views[i].name] = fmt::format("/api/jobs/{}/masks/{}.png", id, i);
  }
  auto write_masks = [mask_pngs, masks_dir = dir / "masks", &stages](bool behind) {
    stages.time(
        "write mask PNGs",
        [&] {
          fs::create_directories(masks_dir);
          parallel_dynamic(static_cast<int64_t>(mask_pngs->size()), thread_plan().files, [&](int64_t i) {
            const auto& [file, mask] = (*mask_pngs)[static_cast<size_t>(i)];
            write_png(file, mask);
          });
        },
        behind);
  };
  json result = {{"masks", mask_files}, {"edit", masks.describe(request)}};
  if (edit.kind == "masks") {
    write_masks(false);
    return result;
  }

  masks.apply_to(input, request);
  input.reference_image = edit.reference;
  if (inpainted.valid()) {
    input.reference_image = stages.time("inpaint reference (waited)", [&] { return inpainted.get(); });
    input.reference_image_source = input.inpainter.name();
  }
  stage("running the network", 0.3);
  const Prediction p = model->predict(*scene, input);
  stages.merge(p.stages);
  GaussianSet gaussians = stages.time("gaussians from the network's maps", [&] { return p.gaussians(); });
  if (refine_requested(edit.refine)) {
    RefineOptions refine = edit.refine;
    int shown = -1;
    refine.progress = [&](const RefineProgress& p) {
      if (static_cast<int>(p.fraction * 100) == shown) return;
      shown = static_cast<int>(p.fraction * 100);
      stage(fmt::format("refining: {:.0f} s left, {} Gaussians (loss {:.4f})", p.eta_s, p.gaussians, p.loss),
            0.4 + 0.5 * p.fraction);
    };
    json report;
    stages.restart_lap();
    gaussians =
        refine_prediction(*scene, p, input, gaussians.to(render_device(predictor->device())), refine, report);
    stages.lap("refine");
    report.erase("losses");
    result["refine"] = report;
  }
  stage("writing the Gaussians", 0.95);
  result.update(write_splats_of(gaussians, dir, id, stages, behind));
  result["reference"] = p.input.reference_source;
  result["model"] = fs::path(model->model_name()).filename().string();  // by name only, as /api/info
  behind.insert(behind.begin(), {"masks", [write_masks] { write_masks(true); }});
  return result;
}

const Predictor& WebServer::State::slower_predictor() {
  std::lock_guard<std::mutex> lock(slower_mutex);
  if (!slower) {
    slower = std::make_unique<Predictor>(options.slower_checkpoint->string(), predictor->device(), predictor->precision());
    spdlog::info("read the released checkpoint {} for the page's slower Run", options.slower_checkpoint->string());
  }
  return *slower;
}

// `working`: the edits' preprocessing, the same for every edit of this server (its --height).
torch::Tensor WebServer::State::reconstruction_depth_in(size_t view, const PreprocessOptions& working) {
  std::lock_guard<std::mutex> lock(reconstruction_depth_mutex);
  torch::Tensor& depth = reconstruction_depth[view];
  if (!depth.defined()) {
    RenderCamera camera;
    camera.camera = normalization.apply(views.get(scene->views.at(view), working).camera);
    depth = render(*reconstruction, camera).depth.squeeze(2).to(torch::kCPU);
  }
  return depth;
}

json WebServer::State::write_splats_of(const GaussianSet& gaussians, const fs::path& dir, int id, StageTimes& stages,
                                       BehindSteps& behind) {
  // In the scene's frame, as infer writes them: the downloads line up with the capture.
  auto cloud = std::make_shared<const SplatCloud>(stages.time(
      "gaussians to splats (host)", [&] { return splats_from_gaussians(in_scene_frame(gaussians, normalization)); }));
  json result = write_cloud_of(cloud, dir, id, stages, behind);
  result["gaussians"] = gaussians.size();
  return result;
}

json WebServer::State::write_cloud_of(std::shared_ptr<const SplatCloud> cloud, const fs::path& dir, int id,
                                      StageTimes& stages, BehindSteps& behind) {
  auto page = std::make_shared<const std::string>(stages.time(
      std::string("encode ") + kPageSplats, [&] { return encode_compressed_splat_ply(*cloud, dir / kPageSplats); }));
  {
    std::lock_guard<std::mutex> lock(mutex);
    page_splats[id] = page;
    while (page_splats.size() > 2) page_splats.erase(page_splats.begin());
  }
  json result = splat_urls(id);
  result["gaussians"] = cloud->size();
  behind.emplace_back("splats", [dir, cloud, page, &stages] { write_splat_files(dir, *page, *cloud, stages); });
  return result;
}

json WebServer::State::run_train(const JobRequest& job, const fs::path& dir, int id,
                                 const std::function<void(const std::string&, double)>& stage, StageTimes& stages,
                                 BehindSteps& behind) {
  ReconstructOptions o;
  o.training = reconstruct_training(job.refine);
  o.height = options.height;
  o.device = predictor ? render_device(predictor->device()) : torch::Device(torch::kCPU);
  int shown = -1;
  o.training.progress = [&](const RefineProgress& p) {
    if (static_cast<int>(p.fraction * 100) == shown) return;
    shown = static_cast<int>(p.fraction * 100);
    stage(fmt::format("training the whole capture: step {}, {} splats (loss {:.4f}), {:.0f} s left", p.step,
                      p.gaussians, p.loss, p.eta_s),
          0.05 + 0.85 * p.fraction);
  };
  stage("training the whole capture: its start points", 0.02);
  stages.restart_lap();
  const ReconstructResult r = reconstruct_scene(*scene, o);
  stages.lap("train the splats (3DGS)");
  stage("writing the splats", 0.95);
  // In the capture's own frame already.
  auto cloud = std::make_shared<const SplatCloud>(
      stages.time("splats to a file's values (host)", [&] { return splats_from_gaussians(r.gaussians.to(torch::kCPU)); }));
  json result = write_cloud_of(cloud, dir, id, stages, behind);
  json report = reconstruct_report(r, o);
  report.erase("views");
  result["trained"] = report;
  return result;
}

json WebServer::State::run_reconstruction(const fs::path& dir, int id,
                                          const std::function<void(const std::string&, double)>& stage,
                                          StageTimes& stages, BehindSteps& behind) {
  SceneInputOptions base;
  base.preprocess.height = options.height;
  base.num_views = options.views;
  base.view_cache = &views;
  base.geometry = options.geometry;  // the cover has no region to cover here
  // The reconstruction a click on a view selects in: the one `masks --click` makes too.
  const SceneInputOptions input = scene_reconstruction_options(base);
  stage("reconstructing the scene as captured (object kept)", 0.2);
  const Prediction p = predictor->predict(*scene, input);
  stages.merge(p.stages);
  // One set (the per-pixel rows and those past the frames joined once), written and kept for the
  // edits' masks: their marked view's depth drawn from it.
  const GaussianSet predicted = p.gaussians();
  GaussianSet kept = predicted;  // the network's dtype (bf16 on a GPU): the rasterizer draws float32
  for (torch::Tensor* t : {&kept.means, &kept.quats, &kept.scales, &kept.opacities, &kept.colors})
    *t = t->to(render_device(predictor->device()), torch::kFloat32);
  selection.set_reconstruction(kept);  // a click on a view selects in it from the server's threads
  reconstruction = std::move(kept);
  {
    std::lock_guard<std::mutex> lock(reconstruction_depth_mutex);
    reconstruction_depth.clear();
  }
  stage("writing the Gaussians", 0.9);
  json result = write_splats_of(predicted, dir, id, stages, behind);
  result["reference_view"] = p.input.views.front().name;
  // The edits scale their depth to points triangulated from the photos, as this prediction did:
  // every view's points (its photo's features matched with its neighbours') are made behind the
  // answer, while the page is painted on, so that an edit only gathers its context views' points
  // (statue, 2 cores: the first edit 0.85 s without, 0.47 s with the features alone).
  if (p.geometry_kind == PointsSource::Photos) {
    std::vector<int> all(scene->views.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    behind.emplace_back("photo points", [this, all, &stages] {
      stages.time("every view's points from the photos (behind)", [&] { prepare_photo_points(*scene, all); }, true);
    });
  }
  return result;
}

void WebServer::State::launch_locked(const JobRequest& request, int id, const fs::path& dir) {
  next_id = std::max(next_id, id + 1);
  fs::create_directories(dir);
  job = Job();
  job.id = id;
  job.kind = request.kind;
  job.state = "running";
  job.stage = "starting";
  queued.emplace(request, dir);
  if (!worker.joinable()) worker = std::thread([this] { worker_loop(); });
  changed.notify_all();
}

void WebServer::State::worker_loop() {
  for (;;) {
    std::pair<JobRequest, fs::path> next;
    {
      std::unique_lock<std::mutex> lock(mutex);
      changed.wait(lock, [&] { return stopping || queued.has_value(); });
      if (!queued) return;
      next = std::move(*queued);
      queued.reset();
      worker_busy = true;
    }
    compute->run([&] { run_job(std::move(next.first), next.second); });
    {
      std::lock_guard<std::mutex> lock(mutex);
      worker_busy = false;
    }
    changed.notify_all();
  }
}

// Lets the worker finish its job (and a queued one), then ends it and the files' writer.
void WebServer::State::stop_worker() {
  {
    std::lock_guard<std::mutex> lock(mutex);
    stopping = true;
  }
  changed.notify_all();
  if (worker.joinable()) worker.join();
  std::thread writer;
  {
    std::lock_guard<std::mutex> lock(mutex);
    writer = std::move(files_writer);
  }
  if (writer.joinable()) writer.join();  // unlocked: it ends with update(), which locks
}

json WebServer::State::run_video(const JobRequest& job, const fs::path& dir, int id,
                                 const std::function<void(const std::string&, double)>& stage) {
  // The official orbit around the scene's cameras, in the scene's frame (infer's PLYs').
  SceneCameraOptions o;
  o.trajectory = "orbit";
  o.frames = 48;
  o.width = o.height = std::max(64, options.height);
  const std::vector<NamedCamera> cameras = scene_cameras(*scene, o);
  const torch::Device device = render_device(predictor ? predictor->device() : torch::Device(torch::kCPU));
  const GaussianSet g = gaussians_from_splats(read_splats(job.ply)).to(device);
  render_frames(g, cameras, {}, {dir / "orbit", {}, {}}, [&](int done, int total) {
    stage(fmt::format("rendering the orbit {}/{}", done, total), 0.9 * done / total);
  });
  if (!ffmpeg_available()) fail("ffmpeg is not installed (scripts/install-deps.sh installs it): no video");
  if (!encode_video(dir / "orbit", dir / "orbit.mp4", 24)) fail("ffmpeg failed to write the video");
  return {{"video", fmt::format("/api/jobs/{}/orbit.mp4", id)}, {"frames", cameras.size()}};
}

json WebServer::State::run_eval(const JobRequest& job, const fs::path& dir, int id) {
  EvalOptions o;
  o.scene_dir = *options.scene_dir;
  o.scene = options.scene;
  o.gaussians = job.ply;
  o.out = dir / "eval";
  o.height = options.height;
  const json metrics = run_evaluation(o);
  return {{"report", fmt::format("/api/jobs/{}/eval/report.html", id)}, {"mean", metrics["mean"]}};
}

void WebServer::State::run_job(JobRequest request, fs::path dir) {
  Stopwatch watch;
  const int id = job.id;
  auto stage = [&](const std::string& text, double progress) {
    update([&](Job& j) {
      j.stage = text;
      j.progress = progress;
    });
    spdlog::info("job {}: {}", id, text);
  };
  // Shared with the writer of the download files, which adds their stages after the answer.
  const auto stages = std::make_shared<StageTimes>();
  BehindSteps behind;
  try {
    if (options.before_job) options.before_job(id);
    json result;
    if (request.kind == "video") {
      result = run_video(request, dir, id, stage);
    } else if (request.kind == "eval") {
      stage("evaluating on the scene's test views", 0.1);
      result = run_eval(request, dir, id);
    } else if (request.kind == "reconstruct") {
      result = run_reconstruction(dir, id, stage, *stages, behind);
    } else if (request.kind == "train") {
      result = run_train(request, dir, id, stage, *stages, behind);
    } else if (request.kind == "fill") {
      result = run_fill(request, dir, id, stage, *stages, behind);
    } else {
      result = run_edit(request, dir, id, stage, *stages, behind);
    }
    const double seconds = watch.ms() / 1000;
    if (!behind.empty()) {  // before the answer: a request for one of them must find it pending
      std::lock_guard<std::mutex> lock(mutex);
      for (const auto& [group, write] : behind) files_pending[id].insert(group);
    }
    update([&](Job& j) {
      j.state = "done";
      j.stage = "done";
      j.progress = 1;
      j.result = result;
      j.seconds = seconds;
      j.stages = stages->to_json();
    });
    spdlog::info("job {}: done in {:.1f} s", id, seconds);
  } catch (const std::exception& e) {
    const double seconds = watch.ms() / 1000;
    update([&](Job& j) {
      j.state = "failed";
      j.error = e.what();
      j.seconds = seconds;
      j.stages = stages->to_json();
    });
    spdlog::error("job {}: {}", id, e.what());
    behind.clear();
  }
  if (!behind.empty()) write_files_behind(id, std::move(behind), stages);
}

void WebServer::State::write_files_behind(int id, BehindSteps steps, std::shared_ptr<StageTimes> stages) {
  // One writer at a time: the previous job's files are written before this job's.
  std::thread previous;
  {
    std::lock_guard<std::mutex> lock(mutex);
    previous = std::move(files_writer);
  }
  if (previous.joinable()) previous.join();
  std::thread next([this, id, steps = std::move(steps), stages] {
    for (const auto& [group, write] : steps) {
      try {
        write();
      } catch (const std::exception& e) {
        spdlog::error("job {}: writing its files ({}): {}", id, group, e.what());
      }
      update([&, group = group](Job& j) {
        const auto pending = files_pending.find(id);
        if (pending != files_pending.end() && pending->second.erase(group) && pending->second.empty())
          files_pending.erase(pending);
        if (j.id == id) j.stages = stages->to_json();
      });
    }
  });
  std::lock_guard<std::mutex> lock(mutex);
  files_writer = std::move(next);
  spdlog::info("job {}: writing its files behind the answer", id);
}

namespace {

// The options checked, the scene read and the output folder taken over: job numbers go on from a
// previous run, whose half-written files are removed.
void open_state(WebServer::State& s) {
  if (s.options.token.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_") !=
      std::string::npos)
    fail("serve --token: only letters, digits, '-' and '_' (it goes into addresses and a cookie)");
  s.token = s.options.no_token ? "" : !s.options.token.empty() ? s.options.token : random_token();
  for (const fs::path& p : s.options.plys)
    if (!fs::is_regular_file(p)) fail_file(p, "no such PLY file");
  if (s.options.scene_dir) {
    s.scene = load_scene(*s.options.scene_dir, s.options.scene);
    s.normalization = scene_normalization(*s.scene);
  }
  s.selection.set_segmenter(s.options.segmenter);
  // Every view's photo encoded for the segmenter behind the page, pausing while a job runs: a
  // click then only decodes.
  if (s.scene && s.options.segmenter)
    s.selection.encode_views_behind(s.scene->views, [&s] {
      std::lock_guard<std::mutex> lock(s.mutex);
      return s.worker_busy || s.queued.has_value();
    }, *s.compute);
  fs::create_directories(s.options.out / "jobs");
  s.out = fs::canonical(s.options.out);
  for (const auto& e : fs::directory_iterator(s.out / "jobs")) {  // job numbers go on from a previous run
    const std::string n = e.path().filename().string();
    if (!n.empty() && std::all_of(n.begin(), n.end(), ::isdigit) && n.size() < 9)
      s.next_id = std::max(s.next_id, std::stoi(n) + 1);
  }
  // A server killed during a job leaves the temporary of the file it was writing: never served
  // (no URL names it), removed here.
  std::vector<fs::path> leftovers;
  for (const auto& e : fs::recursive_directory_iterator(s.out / "jobs"))
    if (e.is_regular_file() && is_atomic_write_leftover(e.path())) leftovers.push_back(e.path());
  for (const fs::path& p : leftovers) fs::remove(p);
  if (!leftovers.empty())
    spdlog::info("removed {} half-written file(s) of an earlier run from {}", leftovers.size(), s.out.string());
}

// What every request passes: the host and token checks, limits, and errors answered as JSON.
void guard_requests(WebServer::State& s) {
  httplib::Server& http = s.http;
  http.set_payload_max_length(s.options.max_upload_bytes);
  // httplib drops a client that sends nothing for 5 s, not one that trickles a byte a second;
  // each such client holds a thread until it is done. 64 threads (httplib's default: 8 on a
  // small machine) keep the page answering beside dozens of them (docs/reliability.md).
  http.new_task_queue = [] { return new httplib::ThreadPool(64); };
  http.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    spdlog::error("request failed: {}", what);
    reply(res, 500, {{"error", what}});
  });
  http.set_pre_routing_handler([&s](const httplib::Request& req, httplib::Response& res) {
    if (auto r = foreign_request(req, s.options.host)) {
      refuse(res, *r);
      return httplib::Server::HandlerResponse::Handled;
    }
    if (auto r = missing_token(req, res, s.token, s.port)) {
      refuse(res, *r);
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  http.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.body.empty())
      reply(res, res.status,
            {{"error", res.status == 413   ? "upload too large"
                       : res.status == 404 ? "not found"
                       : res.status == 405 ? "method not allowed"
                                           : "bad request"}});
  });
}

// The page itself: index.html and its bundle.
void serve_page(httplib::Server& http) {
  auto asset = [](const httplib::Request& req, httplib::Response& res) {
    if (const WebAsset* a = find_web_asset(req.path)) {
      if (!a->gzip_body.empty() && accepts_gzip(req.get_header_value("Accept-Encoding"))) {
        // Sent as gzipped at build time, through a content provider of known length: httplib
        // compresses only a plain body, so it neither compresses it again nor with Brotli.
        res.set_header("Content-Encoding", "gzip");
        res.set_header("Vary", "Accept-Encoding");
        const std::string_view body = a->gzip_body;
        res.set_content_provider(body.size(), std::string(a->content_type),
                                 [body](size_t offset, size_t length, httplib::DataSink& sink) {
                                   return sink.write(body.data() + offset, length);
                                 });
      } else {
        res.set_content(std::string(a->body), std::string(a->content_type));
      }
      return;
    }
    if (req.path == "/" && web_assets().empty()) {
      res.set_content(
          "<!doctype html><meta charset=utf-8><title>instainpaint</title><p>This instainpaint was built without "
          "its web page: run <code>make deps</code> (installs the page's npm packages) and build again. The API "
          "under <a href=\"/api/info\">/api/info</a> works.",
          "text/html; charset=utf-8");
      return;
    }
    refuse(res, {404, "not found"});
  };
  http.Get("/", asset);
  http.Get("/index.html", asset);
  http.Get("/app.js", asset);
}

// What the page reads: the server's state, the scene's views, the PLYs and what jobs wrote.
void serve_reads(WebServer::State& s) {
  httplib::Server& http = s.http;
  http.Get("/api/info", [&s](const httplib::Request&, httplib::Response& res) {
    json info = s.info();
    std::lock_guard<std::mutex> lock(s.mutex);
    info["job"] = s.job.to_json();
    reply(res, 200, info);
  });
  // ?wait=<id>: answers as soon as job <id> has ended, else after half a second with its
  // progress: a client asking again at once sees the end without a polling delay.
  http.Get("/api/job", [&s](const httplib::Request& req, httplib::Response& res) {
    if (req.has_param("wait")) {
      const std::string id = req.get_param_value("wait");
      if (id.empty() || id.size() > 8 || id.find_first_not_of("0123456789") != std::string::npos)
        return refuse(res, {400, "wait must be a job number"});
      return reply(res, 200, s.wait_for_job(std::stoi(id), std::chrono::milliseconds(500)));
    }
    std::lock_guard<std::mutex> lock(s.mutex);
    reply(res, 200, s.job.to_json());
  });
  http.Get(R"(/api/views/(\d{1,6})/(image|mask))", [&s](const httplib::Request& req, httplib::Response& res) {
    const size_t index = std::stoul(req.matches[1]);
    if (!s.scene || index >= s.scene->views.size()) return refuse(res, {404, "no such view"});
    const fs::path file = s.cached_view_file(static_cast<int>(index), req.matches[2] == "mask");
    if (file.empty()) return refuse(res, {404, "this view has no mask"});
    send_file(req, res, file, "image/png");
  });
  http.Get(R"(/api/plys/(\d{1,6}))", [&s](const httplib::Request& req, httplib::Response& res) {
    const size_t index = std::stoul(req.matches[1]);
    if (index >= s.options.plys.size()) return refuse(res, {404, "no such PLY"});
    send_file(req, res, s.options.plys[index], "application/octet-stream");
  });
  // What jobs wrote: their PLY, masks, video and evaluation report (with its sheets and renders).
  http.Get(R"(/api/jobs/(\d{1,8})/(gaussians\.(?:ply|spz|compressed\.ply)|masks/\d{1,6}\.png|orbit\.mp4|fill\.json|eval/report\.html|eval/(sheets|renders)/[^/]+\.png))",
           [&s](const httplib::Request& req, httplib::Response& res) {
             const int id = std::stoi(req.matches[1]);
             if (req.matches[2] == kPageSplats) {
               std::shared_ptr<const std::string> page;
               {
                 std::lock_guard<std::mutex> lock(s.mutex);
                 if (const auto found = s.page_splats.find(id); found != s.page_splats.end()) page = found->second;
               }
               if (page) return send_bytes(req, res, page, kPageSplats);
             }
             s.wait_for_files(id, file_group(req.matches[2]));  // written behind the answer
             // The pattern admits no "/.." and no absolute path; job_file refuses symlinks out.
             const fs::path file = s.job_file(req.matches[1], req.matches[2]);
             if (file.empty()) return refuse(res, {404, "not found"});
             send_file(req, res, file, content_type_of(file));
           });

  // A job's splats as SOG, made from its PLY on the first download (k-means codebooks and
  // WebP images: not worth making for every edit).
  http.Get(R"(/api/jobs/(\d{1,8})/gaussians\.sog)", [&s](const httplib::Request& req, httplib::Response& res) {
    s.wait_for_files(std::stoi(req.matches[1]), "splats");
    const fs::path ply = s.job_file(req.matches[1], "gaussians.ply");
    if (ply.empty()) return refuse(res, {404, "not found"});
    const fs::path sog = ply.parent_path() / "gaussians.sog";
    {
      std::lock_guard<std::mutex> lock(s.sog_mutex);
      if (!fs::exists(sog)) write_splats(sog, read_splats(ply));
    }
    send_file(req, res, sog, "application/octet-stream");
  });
}

}  // namespace

json WebServer::State::select(const httplib::Request& req) {
  if (req.is_multipart_form_data() && !req.has_file("clicks") && req.has_file("ply") && !req.has_file("camera"))
    return {{"total", selection.splats(selection_splats_file(req))->size()}};  // read ahead: the click tool was chosen
  const bool boxed = req.is_multipart_form_data() && req.has_file("box") && req.has_file("view");
  if (!req.is_multipart_form_data() || !(req.has_file("clicks") || boxed) ||
      !(req.has_file("camera") || req.has_file("view")))
    throw Refusal{400, "send multipart/form-data with clicks, and view (a scene view's index) or ply and camera"};
  std::vector<Click> clicks, not_clicks;
  if (req.has_file("clicks") && !(boxed && req.get_file_value("clicks").content.empty()))
    if (auto r = read_clicks(req, clicks)) throw *r;
  if (req.has_file("not_clicks") && !req.get_file_value("not_clicks").content.empty())
    if (auto r = read_clicks(req, not_clicks, "not_clicks")) throw *r;
  try {
    if (req.has_file("view")) {
      std::optional<ViewBox> box;
      if (boxed) box = parse_view_box(req.get_file_value("box").content, "box");
      return select_on_view(req, clicks, not_clicks, box);
    }
    Camera camera;
    if (auto r = read_page_camera(req, out / "select", camera)) throw *r;
    return selection.select_splats(selection_splats_file(req), camera, clicks, not_clicks);
  } catch (const Error& e) {
    throw Refusal{400, e.what()};
  }
}

fs::path WebServer::State::selection_splats_file(const httplib::Request& req) {
  const std::string url = exported_url(req);
  const fs::path ply = splats_of_url(url, /*standard_ply=*/true);
  if (ply.empty()) throw Refusal{400, fmt::format("ply must be the URL of splats this server serves, not '{}'", url)};
  return ply;
}

json WebServer::State::select_on_view(const httplib::Request& req, const std::vector<Click>& clicks,
                                      const std::vector<Click>& not_clicks, const std::optional<ViewBox>& box) {
  if (!scene) throw Refusal{400, "the server was started without --scene: no views to click on"};
  int index = -1;
  try {
    index = std::stoi(req.get_file_value("view").content);
  } catch (const std::exception&) {
  }
  if (index < 0 || index >= static_cast<int>(scene->views.size()))
    throw Refusal{400, fmt::format("view must be the index of one of the scene's {} views", scene->views.size())};
  const View& view = scene->views[static_cast<size_t>(index)];
  // The scene's far bound in the reconstruction's (pose-normalised) frame.
  const std::optional<double> far =
      scene->far ? std::optional<double>(*scene->far / normalization.scale) : std::nullopt;
  std::optional<json> answer =
      selection.select_on_view(view, normalization.apply(view.camera), clicks, not_clicks, far, box);
  if (!answer) throw Refusal{409, "the scene's reconstruction is not ready yet: click again in a moment"};
  return *answer;
}

namespace {

// When the request's `ply` is a job's splats, which that job may still be writing behind its
// answer (an export, a fill, a selection of them): until they are written.
void wait_for_job_splats(WebServer::State& s, const httplib::Request& req) {
  static const std::regex job_url(R"(/api/jobs/(\d{1,8})/.*)");
  std::smatch m;
  const std::string ply = exported_url(req);
  if (std::regex_match(ply, m, job_url)) s.wait_for_files(std::stoi(m[1]), "splats");
}

// What the page starts: masks, edits, videos, evaluations and fills, one job at a time.
void serve_jobs(WebServer::State& s) {
  httplib::Server& http = s.http;
  auto start_job = [&s](const std::string& kind) {
    return [&s, kind](const httplib::Request& req, httplib::Response& res) {
      if (!s.scene && kind != "fill") return refuse(res, {400, "the server was started without --scene: nothing to edit"});
      if ((kind == "masks" || kind == "edit" || kind == "fill") && !s.predictor)
        return refuse(res, {400, "the server was started without a model"});
      if (kind == "video" || kind == "eval" || kind == "fill") wait_for_job_splats(s, req);
      std::lock_guard<std::mutex> lock(s.mutex);
      if (s.job.state == "running")
        return refuse(res, {409, fmt::format("busy: job {} ({}) is running", s.job.id, s.job.stage)});
      const int id = s.next_id;
      const fs::path dir = s.out / "jobs" / std::to_string(id);
      JobRequest request;
      request.kind = kind;
      std::optional<Refusal> refusal;
      try {
        refusal = kind == "video" || kind == "eval" ? s.parse_export(req, request)
                  : kind == "fill"                     ? s.parse_fill(req, request, dir)
                  : kind == "train"                    ? s.parse_train(req, request)
                                                       : s.parse_edit(req, request, dir);
      } catch (const std::exception& e) {
        refusal = Refusal{400, e.what()};
      }
      if (refusal) {
        std::error_code ec;
        fs::remove_all(dir, ec);
        return refuse(res, *refusal);
      }
      s.launch_locked(request, id, dir);
      reply(res, 202, {{"job", id}});
    };
  };
  for (const char* kind : {"masks", "edit", "video", "eval", "fill", "train"})
    http.Post(std::string("/api/") + kind, start_job(kind));
  // Not a job: answered at once, beside a running job.
  http.Post("/api/select", [&s](const httplib::Request& req, httplib::Response& res) {
    wait_for_job_splats(s, req);
    try {
      reply(res, 200, s.compute->run_if_idle([&] { return s.select(req); }));
    } catch (const Refusal& r) {
      refuse(res, r);
    } catch (const std::exception& e) {
      refuse(res, {400, e.what()});
    }
  });
}

}  // namespace

WebServer::WebServer(ServeOptions options, const Predictor* predictor) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.options = std::move(options);
  s.predictor = predictor;
  s.compute = s.options.compute ? s.options.compute : std::make_shared<ComputeThread>();
  open_state(s);
  guard_requests(s);
  serve_page(s.http);
  serve_reads(s);
  serve_jobs(s);
  // Last: nothing after it may throw while the job's thread runs.
  if (s.options.reconstruct_at_start && s.scene && s.predictor && s.options.plys.empty()) {
    JobRequest request;
    request.kind = "reconstruct";
    std::lock_guard<std::mutex> lock(s.mutex);
    s.launch_locked(request, s.next_id, s.out / "jobs" / std::to_string(s.next_id));
  }
}

WebServer::~WebServer() {
  stop();
  wait_for_job();
}

int WebServer::bind() {
  State& s = *state_;
  if (s.options.port == 0) {
    s.port = s.http.bind_to_any_port(s.options.host);
    if (s.port < 0) fail("serve: cannot listen on {}", s.options.host);
    return s.port;
  }
  if (!s.http.bind_to_port(s.options.host, s.options.port))
    fail("serve: cannot listen on {}:{} (in use? --port picks another)", s.options.host, s.options.port);
  s.port = s.options.port;
  return s.port;
}

const std::string& WebServer::token() const { return state_->token; }

void WebServer::run() { state_->http.listen_after_bind(); }

void WebServer::stop() { state_->http.stop(); }

void WebServer::wait_for_job() {
  State& s = *state_;
  std::thread writer;
  {
    std::unique_lock<std::mutex> lock(s.mutex);
    s.changed.wait(lock, [&] { return !s.worker_busy && !s.queued; });
    writer = std::move(s.files_writer);
  }
  if (writer.joinable()) writer.join();
}

}  // namespace ii
