#pragma once
// `instainpaint serve`: a local HTTP server for the browser page (web/): it shows splat PLYs
// and a scene's cameras and views, and runs one-mask edits (mask propagation, the network,
// refinement) as background jobs, one at a time.
//
// Safety: binds to loopback unless told otherwise; answers only requests addressed to one of its
// names (Host) that carry its token (made at start: ?token= in the address it prints, then a
// cookie; or the header X-Instainpaint-Token), and state-changing ones only from its own page
// (Origin); serves only the embedded page, the scene's
// views (by index, never by path), the PLYs it was started with (by index) and the files its
// jobs wrote under `out`; uploads are size-limited and must be PNG or JPEG of the right size;
// a request it cannot serve gets a 4xx with a JSON {"error"}; a job that fails reports its
// error and leaves the server running.
//
// HTTP API (all JSON unless noted):
//   GET  /api/info                 scene views and cameras (the scene's frame, OpenGL axes,
//                                  as infer's and the jobs' splats), PLYs, the current job
//   GET  /api/views/<i>/image      view i as PNG (decoded, undistorted); /mask its object mask
//   GET  /api/plys/<i>             the i-th PLY given at start (?download=1: as an attachment)
//   POST /api/masks                multipart view, mask[, mode]: propagate one mask (a job)
//   POST /api/edit                 multipart view, mask[, mode, reference, refine]: edit (a job)
//   POST /api/fill                 multipart ply=<splats on screen>, box=cx,cy,cz,sx,sy,sz[,rx,ry,rz]
//                                  or camera=<a camera list of one (render --cameras' JSON)> and
//                                  mask (PNG of the camera's size) or clicks=x,y;x,y (the objects under them)
//                                  [, refine]: remove the region and fill the hole (a job;
//                                  no scene needed, its cameras used when there is one)
//   POST /api/select               multipart ply, camera, clicks=x,y;x,y: the splats of the objects under
//                                  the clicks (fill/region.h), answered at once: {selected, total,
//                                  pixels, width, height, runs (the view's pixels row by row,
//                                  alternately outside and inside the selection), ms}; ply alone:
//                                  the splats read ahead of the clicks ({total})
//   POST /api/train                length=fast|balanced|best|TIME|STEPS (at most 20 minutes or 30,000
//                                  steps): 3D Gaussian splatting of the whole capture (reconstruct),
//                                  a job; result.splats as an edit's, result.trained its report
//   POST /api/video, /api/eval     ply=<a served splat file's URL>: an orbit video (a job), the
//                                  SPIn-NeRF evaluation on the scene's test views (a job)
//   GET  /api/job[?wait=<id>]      the current or last job: state, stage, progress, result, and
//                                  where its time went ("stages", common/stage_times.h);
//                                  with wait, answered as soon as job <id> ends (else after half
//                                  a second). Kind "reconstruct": the scene with its object,
//                                  started by the server itself when it has a scene and no PLYs.
//   GET  /api/jobs/<id>/<file>     what job <id> wrote: gaussians.compressed.ply (what the page
//                                  loads: result.splats, sent from memory at first),
//                                  gaussians.ply and .spz (written after the answer: a request
//                                  waits for them), gaussians.sog (made on the first request),
//                                  masks/<view index>.png (also after the answer),
//                                  orbit.mp4, eval/report.html (and its sheets, renders)
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/compute_thread.h"
#include "data/scene.h"
#include "predict/predictor.h"
#include "segment/segmenter.h"

namespace ii {

struct ServeOptions {
  std::optional<std::filesystem::path> scene_dir;  // editing needs a scene
  SceneOptions scene;
  std::vector<std::filesystem::path> plys;  // shown in the viewer
  std::filesystem::path out = "serve-out";  // jobs write here (out/jobs/<id>/)
  std::string host = "127.0.0.1";
  int port = 8080;  // 0 = any free port
  int height = 256;  // working height of edits
  int views = 4;     // context views of edits
  GeometryOptions geometry;  // SceneInputOptions::geometry of every prediction
  size_t max_upload_bytes = 32u << 20;
  // Every request must carry this token; empty: a random one is made (WebServer::token()).
  std::string token;
  bool no_token = false;  // serve without a token (any local program and website can then drive it)
  std::function<void(int job)> before_job;  // called on the job's thread before it works (tests)
  // With a scene, a model and no PLYs: the first job reconstructs the scene as captured (object
  // kept), so that the page shows it in 3D at once (serve sets it; tests choose).
  bool reconstruct_at_start = false;
  // The page's clicks prompt this network (SAM, MobileSAM) when given: a photo's or the splats'
  // outline at once, shift-click a point on the object, alt-click a point that is not.
  std::shared_ptr<const Segmenter> segmenter;
  // What paints the reference's region when the page sends no reference (Run) and Fill's by
  // default: a classical method, or LaMa (serve --inpainter FILE; the page may then ask for "lama").
  Inpainter inpainter;
  // On a CPU, with the cache's released checkpoint and the built-in model for Run (serve's
  // --checkpoint auto): the released one, offered as a slower, better Run (the page's "model").
  std::optional<std::filesystem::path> slower_checkpoint;
  // The thread of every job's and click's LibTorch work (common/compute_thread.h): serve's, on
  // which it also read the networks; null: the server makes its own.
  std::shared_ptr<ComputeThread> compute;
};

class WebServer {
 public:
  // `predictor` (may be null: no editing) must outlive the server.
  WebServer(ServeOptions options, const Predictor* predictor);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Binds the socket; returns the port (the free one chosen when options.port is 0).
  int bind();
  // The token requests must carry (empty with no_token).
  const std::string& token() const;
  // Serves until stop() (from another thread or a signal handler's thread).
  void run();
  void stop();
  // Waits for a running job to end (tests).
  void wait_for_job();

  // Opaque: defined in server.cpp, where the steps that build the server take it.
  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace ii
