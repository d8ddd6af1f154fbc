// `instainpaint serve`'s server on loopback, driven by an HTTP client: what it serves, what it
// refuses (paths outside its folders, bad uploads, a second job), that a failing job leaves it
// running, and a whole one-mask edit.
#include <gtest/gtest.h>

#include <algorithm>
#include <future>
#include <map>
#include <thread>

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include "inpaint/lama_inpainter.h"
#include "camera/trajectory.h"
#include "io/image.h"
#include "io/ply.h"
#include "io/splat_file.h"
#include "io/spz.h"
#include "io/video.h"
#include "synth/synth_scene.h"
#include "synth/synth_writer.h"
#include "test_support.h"
#include "web/assets.h"
#include "web/server.h"

// Last: it includes <resolv.h>, whose `_res` macro breaks Eigen headers included after it.
#include <httplib.h>

namespace ii {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// A small room with an object, masks in every view (the edits' scene).
const fs::path& room() {
  static const fs::path dir = [] {
    synth::SynthOptions so;
    so.views = 5;
    so.test_views = 1;
    so.width = 48;
    so.height = 40;
    so.object = synth::ObjectSource::procedural;
    const fs::path d = test::temp_dir("serve-room") / "room";
    synth::write_synth_scene(synth::generate_scene(so, 5), d, {});
    return d;
  }();
  return dir;
}

const Predictor& default_model() {
  static const Predictor predictor("", torch::kCPU, Precision::Float32);
  return predictor;
}

// The server on a free loopback port, running in a thread for the test's lifetime.
struct RunningServer {
  std::unique_ptr<WebServer> server;
  std::thread thread;
  std::unique_ptr<httplib::Client> client;
  int port = 0;
  fs::path out;

  static constexpr const char* token = "test-token-7f3a";

  explicit RunningServer(ServeOptions o, const Predictor* predictor = &default_model()) {
    o.port = 0;
    o.host = "127.0.0.1";
    if (o.token.empty() && !o.no_token) o.token = token;
    if (o.out == "serve-out") o.out = test::temp_dir("serve-out");
    out = o.out;
    server = std::make_unique<WebServer>(o, predictor);
    port = server->bind();
    thread = std::thread([this] { server->run(); });
    client = std::make_unique<httplib::Client>("127.0.0.1", port);
    client->set_read_timeout(60, 0);
    if (!o.no_token) client->set_default_headers({{"X-Instainpaint-Token", o.token}});
  }
  ~RunningServer() {
    server->stop();
    thread.join();
  }
  // Waits for the current job to end; returns its state.
  json finished_job() {
    server->wait_for_job();
    return json::parse(client->Get("/api/job")->body);
  }
};

ServeOptions room_options() {
  ServeOptions o;
  o.scene_dir = room();
  o.height = 40;
  return o;
}

httplib::MultipartFormDataItems edit_form(const std::string& view, const std::string& mask_bytes,
                                          const std::string& extra_name = "", const std::string& extra = "") {
  httplib::MultipartFormDataItems items = {{"view", view, "", ""}, {"mask", mask_bytes, "mask.png", "image/png"}};
  if (!extra_name.empty()) items.push_back({extra_name, extra, "", ""});
  return items;
}

// The message of a refused request.
std::string error_of(const httplib::Result& r) { return json::parse(r->body)["error"].get<std::string>(); }

std::string view_mask_bytes(const std::string& view) {
  return test::file_bytes(room() / "images_4" / "label" / (view + ".png"));
}

TEST(Serve, InfoViewsAndPlys) {
  ServeOptions o = room_options();
  const fs::path ply = test::temp_dir("serve-ply") / "a.ply";
  test::write_bytes(ply, "ply\nformat binary_little_endian 1.0\nelement vertex 0\nend_header\n");
  o.plys = {ply};
  RunningServer s(o);

  const auto info = s.client->Get("/api/info");
  ASSERT_EQ(info->status, 200);
  const json j = json::parse(info->body);
  ASSERT_EQ(j["scene"]["views"].size(), 5u);
  EXPECT_EQ(j["scene"]["views"][0]["name"], "view_000");
  EXPECT_EQ(j["scene"]["views"][0]["width"], 48);
  EXPECT_EQ(j["scene"]["views"][0]["c2w"].size(), 16u);
  EXPECT_EQ(j["scene"]["test_views"], 1);
  EXPECT_EQ(j["plys"][0]["url"], "/api/plys/0");
  EXPECT_TRUE(j["editing"]);
  EXPECT_EQ(j["job"]["state"], "idle");

  const auto image = s.client->Get("/api/views/1/image");
  ASSERT_EQ(image->status, 200);
  EXPECT_EQ(image->get_header_value("Content-Type"), "image/png");
  const fs::path back = s.out / "back.png";
  test::write_bytes(back, image->body);
  EXPECT_EQ(probe_image(back).width, 48);
  EXPECT_EQ(s.client->Get("/api/views/1/mask")->status, 200);

  const auto p = s.client->Get("/api/plys/0?download=1");
  ASSERT_EQ(p->status, 200);
  EXPECT_EQ(p->body, test::file_bytes(ply));
  EXPECT_EQ(p->get_header_value("Content-Disposition"), "attachment; filename=\"a.ply\"");

  // The page (when built with it), or the page that says how to get it.
  const auto page = s.client->Get("/");
  ASSERT_EQ(page->status, 200);
  EXPECT_NE(page->body.find(web_assets().empty() ? "make deps" : "/app.js"), std::string::npos);
}

// The page's 3 MB bundle goes out gzipped at build time whenever the browser takes gzip (every
// browser does; it asks for Brotli first, which the server compressed at each load in 5.7 s),
// and as it is otherwise.
TEST(Serve, TheBundleIsSentGzippedAsBuilt) {
  const WebAsset* bundle = find_web_asset("/app.js");
  if (!bundle) GTEST_SKIP() << "built without the web page (no web/node_modules: make deps)";
  RunningServer s(room_options());
  const std::string bytes(bundle->body);
  for (const char* accepted : {"gzip, deflate, br, zstd", "br;q=1.0, GZIP;q=0.5"}) {
    s.client->set_decompress(false);
    const auto raw = s.client->Get("/app.js", {{"Accept-Encoding", accepted}});
    ASSERT_TRUE(raw) << accepted;
    EXPECT_EQ(raw->get_header_value("Content-Encoding"), "gzip") << accepted;
    EXPECT_EQ(raw->body, std::string(bundle->gzip_body)) << accepted;
    EXPECT_EQ(raw->get_header_value("Content-Length"), std::to_string(bundle->gzip_body.size())) << accepted;
    s.client->set_decompress(true);  // zlib, through httplib's client: decodes to the bundle
    const auto decoded = s.client->Get("/app.js", {{"Accept-Encoding", accepted}});
    ASSERT_TRUE(decoded) << accepted;
    EXPECT_TRUE(decoded->body == bytes) << accepted << ": " << decoded->body.size() << " bytes";
  }
  for (const char* accepted : {"", "identity", "deflate"}) {
    const auto plain = s.client->Get("/app.js", {{"Accept-Encoding", accepted}});
    ASSERT_TRUE(plain) << accepted;
    EXPECT_EQ(plain->get_header_value("Content-Encoding"), "") << accepted;
    EXPECT_TRUE(plain->body == bytes) << accepted << ": " << plain->body.size() << " bytes";
  }
}

TEST(Serve, NothingOutsideItsFoldersIsServed) {
  RunningServer s(room_options());
  // A symlink planted in a job's folder, pointing out of it.
  fs::create_directories(s.out / "jobs" / "77" / "masks");
  fs::create_symlink("/etc/hostname", s.out / "jobs" / "77" / "gaussians.ply");
  fs::create_symlink("/etc/hostname", s.out / "jobs" / "77" / "masks" / "0.png");
  for (const char* path :
       {"/api/jobs/77/gaussians.ply", "/api/jobs/77/masks/0.png", "/api/jobs/77/../../../etc/passwd",
        "/api/jobs/1/%2e%2e/%2e%2e/etc/passwd", "/../../etc/passwd", "//etc/passwd", "/api/views/9/image",
        "/api/views/-1/image", "/api/plys/0", "/api/plys/../../etc/passwd", "/cache/view-0.png", "/api/views/0/../../x",
        "/etc/passwd", "/app.js/../../etc/passwd"}) {
    const auto r = s.client->Get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, 404) << path;
    EXPECT_TRUE(json::parse(r->body).contains("error")) << path << ": " << r->body;
  }
  EXPECT_EQ(s.client->Delete("/api/info")->status / 100, 4);
}

TEST(Serve, BadUploadsAreRefusedWithTheReason) {
  ServeOptions o = room_options();
  o.max_upload_bytes = 64 << 10;
  RunningServer s(o);
  const std::string mask = view_mask_bytes("view_001");

  auto r = s.client->Post("/api/masks", "view=view_001", "application/x-www-form-urlencoded");
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r), "send multipart/form-data with view and mask");
  r = s.client->Post("/api/masks", edit_form("nope", mask));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r), "no view 'nope' in the scene");
  r = s.client->Post("/api/masks", edit_form("view_001", "#!/bin/sh\nrm -rf /\n"));
  EXPECT_EQ(r->status, 415);
  EXPECT_EQ(error_of(r), "mask: not a PNG or JPEG image");
  r = s.client->Post("/api/masks", edit_form("view_001", test::file_bytes(room() / "reference.png").substr(0, 40)));
  EXPECT_EQ(r->status, 400);  // a PNG signature with nothing behind it
  Image big(64, 64, 1);
  write_png(s.out / "big.png", big);
  r = s.client->Post("/api/masks", edit_form("view_001", test::file_bytes(s.out / "big.png")));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r), "mask: the mask is 64x64 but view view_001 is 48x40");
  write_png(s.out / "empty.png", Image(48, 40, 1));
  r = s.client->Post("/api/masks", edit_form("view_001", test::file_bytes(s.out / "empty.png")));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r), "mask: the mask is empty: mark the region in white");
  r = s.client->Post("/api/masks", edit_form("view_001", mask, "mode", "paint"));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r), "mode must be remove or insert");
  for (const char* refine : {"1e9", "5001", "21m", "quick", ""}) {
    r = s.client->Post("/api/edit", edit_form("view_001", mask, "refine", refine));
    EXPECT_EQ(r->status, 400) << refine;
    EXPECT_EQ(error_of(r), "refine must be fast, balanced or best, a time up to 20m, or a number of steps up to 5000")
        << refine;
  }
  r = s.client->Post("/api/edit", edit_form("view_001", mask, "selected", "yes"));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r), "selected must be 0 or 1");
  r = s.client->Post("/api/edit", edit_form("view_001", mask, "mode", "insert"));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r), "insert needs a reference: the view's photo with the new object painted in");
  // A reference far larger than the view is refused from its header, before decoding.
  write_png(s.out / "huge.png", Image(400, 400, 3));
  r = s.client->Post("/api/edit", edit_form("view_001", mask, "reference", test::file_bytes(s.out / "huge.png")));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r),
            "reference: 400x400 pixels, more than this server decodes for view view_001 (48x40: at most 4 times its "
            "pixels)");
  // A decompression bomb (16000 x 16000 pixels: 3 GB decoded) costs the server no memory:
  // refused by every image reader's probe (io/image.cpp), or by the server's for its views.
  const double peak = test::peak_rss_mb();
  r = s.client->Post("/api/edit", edit_form("view_001", test::png_header(16000, 16000)));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r), "mask: 16000x16000 pixels, more than instainpaint decodes (at most 134 million)");
  r = s.client->Post("/api/edit", edit_form("view_001", mask, "reference", test::png_header(4000, 4000)));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r),
            "reference: 4000x4000 pixels, more than this server decodes for view view_001 (48x40: at most 4 times its "
            "pixels)");
  EXPECT_LT(test::peak_rss_mb() - peak, 100.0);
  // A box on a view's photo (GrabCut in it without a segmenter): refused when it is not a box, when
  // it reaches outside the photo or covers all of it, with a click outside it.
  auto select = [&](httplib::MultipartFormDataItems items) { return s.client->Post("/api/select", items); };
  EXPECT_EQ(error_of(select({{"view", "1", "", ""}, {"box", "2,3,60,30", "", ""}})),
            "view view_001: the box 2,3,60,30 reaches outside its photo (48x40)");
  EXPECT_EQ(error_of(select({{"view", "1", "", ""}, {"box", "0,0,48,40", "", ""}})).substr(0, 65),
            "view view_001: the box 0,0,48,40 covers the whole photo (48x40): ");
  EXPECT_EQ(error_of(select({{"view", "1", "", ""}, {"box", "2,3,20,30", "", ""}, {"clicks", "40,35", "", ""}})),
            "view view_001: the click (40, 35) is outside the box 2,3,20,30: clicks with a box are on the object inside "
            "it");
  EXPECT_EQ(error_of(select({{"view", "1", "", ""}, {"box", "20,3,2,30", "", ""}})),
            "box 20,3,2,30: expected X0,Y0,X1,Y1 with X1 > X0 and Y1 > Y0");
  EXPECT_EQ(error_of(select({{"view", "1", "", ""}, {"box", "2,3,nan,30", "", ""}})),
            "box 2,3,nan,30: expected X0,Y0,X1,Y1 with X1 > X0 and Y1 > Y0");
  r = s.client->Post("/api/masks", edit_form("view_001", std::string(80 << 10, 'x')));
  EXPECT_EQ(r->status, 413);
  // Nothing ran, nothing was left behind.
  EXPECT_EQ(json::parse(s.client->Get("/api/job")->body)["state"], "idle");
  EXPECT_TRUE(fs::is_empty(s.out / "jobs"));
}

TEST(Serve, OtherWebsitesAreRefused) {
  RunningServer s(room_options());
  const std::string mask = view_mask_bytes("view_001");
  // DNS rebinding: a foreign name resolving to loopback.
  auto r = s.client->Get("/api/info", {{"Host", "evil.example"}});
  EXPECT_EQ(r->status, 403);
  EXPECT_EQ(error_of(r),
            "Host 'evil.example' is not a name of this server (open it as http://127.0.0.1:<port>/ or by the --host it "
            "was started with)");
  // A cross-origin form post from a page elsewhere.
  r = s.client->Post("/api/masks", {{"Origin", "http://evil.example"}}, edit_form("view_001", mask));
  EXPECT_EQ(r->status, 403);
  EXPECT_EQ(error_of(r), "a request from another website (http://evil.example) may not change anything here");
  EXPECT_EQ(json::parse(s.client->Get("/api/job")->body)["state"], "idle");
  EXPECT_TRUE(fs::is_empty(s.out / "jobs"));
  // The server's own names and page are served.
  EXPECT_EQ(s.client->Get("/api/info", {{"Host", "localhost:8080"}})->status, 200);
  EXPECT_EQ(s.client->Get("/api/info", {{"Host", "[::1]:8080"}})->status, 200);
  const std::string own = "http://127.0.0.1:" + std::to_string(s.port);
  EXPECT_EQ(s.client->Post("/api/masks", {{"Origin", own}}, edit_form("view_001", mask))->status, 202);
}

TEST(Serve, EveryRequestNeedsTheToken) {
  RunningServer s(room_options());
  httplib::Client bare("127.0.0.1", s.port);
  const std::string port = std::to_string(s.port);
  const std::string advice = "token: open the address that `instainpaint serve` printed at start (http://...:" + port +
                             "/?token=...), or send the token as the X-Instainpaint-Token header";
  for (const char* path : {"/", "/api/info", "/api/views/0/image"}) {
    auto r = bare.Get(path);
    EXPECT_EQ(r->status, 403) << path;
    EXPECT_EQ(error_of(r), "missing " + advice) << path;
  }
  auto r = bare.Post("/api/masks", edit_form("view_001", view_mask_bytes("view_001")));
  EXPECT_EQ(r->status, 403);
  EXPECT_EQ(error_of(r), "missing " + advice);
  EXPECT_TRUE(fs::is_empty(s.out / "jobs"));
  EXPECT_EQ(error_of(bare.Get("/api/info?token=test-token-7f3b")), "wrong " + advice);
  EXPECT_EQ(error_of(bare.Get("/api/info", {{"X-Instainpaint-Token", "test-token-7f3"}})), "wrong " + advice);
  // Another server's cookie (cookies are per host name, not per port) is no token here.
  EXPECT_EQ(error_of(bare.Get("/api/info", {{"Cookie", "instainpaint-token-1=test-token-7f3a"}})), "missing " + advice);

  // The printed address: answered, and the cookie that the page's own requests then carry.
  r = bare.Get("/?token=test-token-7f3a");
  EXPECT_EQ(r->status, 200);
  const std::string cookie = "instainpaint-token-" + port + "=test-token-7f3a";
  EXPECT_EQ(r->get_header_value("Set-Cookie"), cookie + "; Path=/; HttpOnly; SameSite=Strict");
  EXPECT_EQ(bare.Get("/api/info", {{"Cookie", "other=1; " + cookie}})->status, 200);
  EXPECT_EQ(bare.Get("/api/info", {{"X-Instainpaint-Token", "test-token-7f3a"}})->status, 200);
}

TEST(Serve, WithoutATokenOnlyWhenAskedTo) {
  ServeOptions o = room_options();
  o.no_token = true;
  RunningServer s(o);
  httplib::Client bare("127.0.0.1", s.port);
  EXPECT_EQ(bare.Get("/api/info")->status, 200);
  // A token of one's own must fit an address and a cookie.
  ServeOptions bad = room_options();
  bad.token = "a b";
  EXPECT_EQ(test::error_message([&] { WebServer server(bad, nullptr); }),
            "serve --token: only letters, digits, '-' and '_' (it goes into addresses and a cookie)");
}

TEST(Serve, AKilledRunsHalfWrittenFilesAreRemovedAndNumbersGoOn) {
  ServeOptions o = room_options();
  o.out = test::temp_dir("serve-killed");
  const fs::path job = o.out / "jobs" / "3";
  fs::create_directories(job / "masks");
  test::write_bytes(job / "masks" / "0.png", "done");
  test::write_bytes(job / "masks" / ".1.png.tmp59b2bf1f", "half");  // killed while writing
  test::write_bytes(job / ".notes.tmp", "not ours");
  RunningServer s(o);
  EXPECT_TRUE(fs::exists(job / "masks" / "0.png"));
  EXPECT_FALSE(fs::exists(job / "masks" / ".1.png.tmp59b2bf1f"));
  EXPECT_TRUE(fs::exists(job / ".notes.tmp"));
  EXPECT_EQ(s.client->Get("/api/jobs/3/gaussians.ply")->status, 404);
  EXPECT_EQ(s.client->Post("/api/masks", edit_form("view_001", view_mask_bytes("view_001")))->status, 202);
  EXPECT_EQ(s.finished_job()["id"], 4);
}

TEST(Serve, OneJobAtATimeAndAFailedJobLeavesTheServerRunning) {
  ServeOptions o = room_options();
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  o.before_job = [released](int) { released.wait(); };  // holds the first job until checked
  RunningServer s(o);
  const std::string mask = view_mask_bytes("view_002");

  // A reference of the wrong size fails inside the job (preparing the network's input).
  Image small(10, 10, 3, 0.5f);
  write_png(s.out / "small.png", small);
  httplib::MultipartFormDataItems form = edit_form("view_002", mask);
  form.push_back({"reference", test::file_bytes(s.out / "small.png"), "ref.png", "image/png"});
  auto r = s.client->Post("/api/edit", form);
  ASSERT_EQ(r->status, 202) << r->body;
  EXPECT_EQ(json::parse(r->body)["job"], 1);
  const auto busy = s.client->Post("/api/masks", edit_form("view_002", mask));
  EXPECT_EQ(busy->status, 409);
  EXPECT_EQ(json::parse(busy->body)["error"].get<std::string>().rfind("busy: job 1", 0), 0u) << busy->body;
  release.set_value();

  const json failed = s.finished_job();
  EXPECT_EQ(failed["state"], "failed");
  EXPECT_NE(failed["error"].get<std::string>().find("reference image is 10x10"), std::string::npos) << failed;
  EXPECT_EQ(s.client->Get("/api/info")->status, 200);

  // The next job runs.
  r = s.client->Post("/api/masks", edit_form("view_002", mask));
  ASSERT_EQ(r->status, 202) << r->body;
  const json done = s.finished_job();
  EXPECT_EQ(done["id"], 2);
  EXPECT_EQ(done["state"], "done") << done;
  EXPECT_EQ(done["result"]["masks"].size(), 5u);
}

TEST(Serve, EditFromOneMaskWritesAndServesTheGaussians) {
  RunningServer s(room_options());
  auto r = s.client->Post("/api/edit", edit_form("view_003", view_mask_bytes("view_003"), "refine", "2"));
  ASSERT_EQ(r->status, 202) << r->body;
  const int id = json::parse(r->body)["job"];
  // ?wait= answers with the job once it has ended (or with its progress after half a second).
  json job = json::parse(s.client->Get("/api/job?wait=" + std::to_string(id))->body);
  while (job["state"] == "running") job = json::parse(s.client->Get("/api/job?wait=" + std::to_string(id))->body);
  ASSERT_EQ(job["state"], "done") << job;
  EXPECT_EQ(job["kind"], "edit");
  EXPECT_EQ(job["result"]["refine"]["steps"], 2);
  EXPECT_EQ(job["result"]["reference"], "ns");
  // The page loads the compressed PLY, written before the answer.
  EXPECT_EQ(job["result"]["splats"], fmt::format("/api/jobs/{}/gaussians.compressed.ply", id));
  const auto page = s.client->Get(job["result"]["splats"].get<std::string>());
  ASSERT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("element chunk"), std::string::npos);
  // The downloads are written behind the answer: a request for one waits until it is there.
  const auto ply = s.client->Get(job["result"]["ply"].get<std::string>());
  ASSERT_EQ(ply->status, 200);
  EXPECT_EQ(ply->body.rfind("ply\n", 0), 0u);
  EXPECT_LT(page->body.size() * 3, ply->body.size());
  // Sent from memory before its file is written: the same bytes as the file.
  s.finished_job();
  EXPECT_EQ(page->body, test::file_bytes(s.out / "jobs" / std::to_string(id) / "gaussians.compressed.ply"));
  const auto spz = s.client->Get(job["result"]["spz"].get<std::string>());
  ASSERT_EQ(spz->status, 200);
  const SplatCloud from_spz = decode_spz(reinterpret_cast<const uint8_t*>(spz->body.data()), spz->body.size(), "spz");
  EXPECT_EQ(from_spz.size(), job["result"]["gaussians"].get<size_t>());
  EXPECT_LT(spz->body.size() * 3, ply->body.size());  // 68 bytes per Gaussian against about 17
  // Where the time went: the masks' work, the prediction, the files (those behind the answer
  // marked so, recorded once written).
  job = s.finished_job();
  std::map<std::string, json> stages;
  for (const json& stage : job["stages"]) stages[stage["stage"]] = stage;
  for (const char* name : {"masks: propagate", "prepare context views", "network input", "upload", "network",
                           "refine", "gaussians to splats (host)", "encode gaussians.compressed.ply"}) {
    ASSERT_TRUE(stages.count(name)) << name << " in " << job["stages"];
    EXPECT_FALSE(stages[name].contains("behind")) << name;
  }
  for (const char* name : {"inpaint reference (ns)", "write mask PNGs", "write gaussians.compressed.ply",
                           "write gaussians.ply", "write gaussians.spz"}) {
    ASSERT_TRUE(stages.count(name)) << name << " in " << job["stages"];
    EXPECT_EQ(stages[name]["behind"], true) << name;
  }
  EXPECT_EQ(s.client->Get("/api/job?wait=x")->status, 400);
  EXPECT_EQ(error_of(s.client->Get("/api/job?wait=x")), "wait must be a job number");
  // SOG is made on the first request.
  const fs::path sog_file = s.out / "jobs" / std::to_string(job["id"].get<int>()) / "gaussians.sog";
  EXPECT_FALSE(fs::exists(sog_file));
  const auto sog = s.client->Get("/api/jobs/" + std::to_string(job["id"].get<int>()) + "/gaussians.sog");
  ASSERT_EQ(sog->status, 200);
  EXPECT_EQ(sog->body.size(), fs::file_size(sog_file));
  EXPECT_EQ(read_splats(sog_file).size(), from_spz.size());
  EXPECT_EQ(s.client->Get("/api/jobs/99/gaussians.sog")->status, 404);
  const auto mask = s.client->Get(job["result"]["masks"]["view_000"].get<std::string>());
  ASSERT_EQ(mask->status, 200);
  EXPECT_EQ(mask->get_header_value("Content-Type"), "image/png");
}

// Opened on a scene alone (as `serve --scene` does), the server's first job reconstructs it with
// its object; the page shows that PLY at once and opens the editor on the reference view.
TEST(Serve, AScenesReconstructionIsTheFirstJob) {
  ServeOptions o = room_options();
  o.reconstruct_at_start = true;
  RunningServer s(o);
  const json info = json::parse(s.client->Get("/api/info")->body);
  EXPECT_EQ(info["job"]["kind"], "reconstruct") << info;
  const json job = s.finished_job();
  ASSERT_EQ(job["state"], "done") << job;
  EXPECT_EQ(job["result"]["ply"], "/api/jobs/" + std::to_string(job["id"].get<int>()) + "/gaussians.ply");
  const auto ply = s.client->Get(job["result"]["ply"].get<std::string>());
  ASSERT_EQ(ply->status, 200);
  const fs::path file = s.out / "jobs" / std::to_string(job["id"].get<int>()) / "gaussians.ply";
  EXPECT_EQ(ply->body.size(), fs::file_size(file));
  EXPECT_EQ(read_splat_ply(file).opacity_logit.size(), job["result"]["gaussians"].get<size_t>());
  const std::string reference = job["result"]["reference_view"];
  EXPECT_EQ(reference.rfind("view_", 0), 0u) << reference;
  // Not with PLYs to show: nothing starts.
  ServeOptions with_ply = room_options();
  with_ply.reconstruct_at_start = true;
  with_ply.plys = {file};
  RunningServer t(with_ply);
  EXPECT_EQ(json::parse(t.client->Get("/api/info")->body)["job"]["state"], "idle");
}

// A capture without depth maps or points: its reconstruction scales the depth to points
// triangulated from the photos, and every view's points are made behind the answer, so that an
// edit only gathers its context views'; with --align-depth none neither happens.
TEST(Serve, ACapturesPhotoPointsAreMadeBehindItsReconstruction) {
  II_REQUIRE_SHARED(dir, "data/statue");
  auto stage_names = [](const json& job) {
    std::vector<std::string> names;
    for (const json& st : job["stages"]) names.push_back(st["stage"].get<std::string>());
    return names;
  };
  const std::string behind = "every view's points from the photos (behind)";
  ServeOptions o;
  o.scene_dir = dir;
  o.height = 64;
  o.reconstruct_at_start = true;
  {
    RunningServer s(o);
    const json job = s.finished_job();
    ASSERT_EQ(job["state"], "done") << job;
    const std::vector<std::string> names = stage_names(job);
    EXPECT_NE(std::find(names.begin(), names.end(), behind), names.end()) << job["stages"];
  }
  o.geometry.align_depth = DepthPoints::none;
  RunningServer s(o);
  const json job = s.finished_job();
  ASSERT_EQ(job["state"], "done") << job;
  const std::vector<std::string> names = stage_names(job);
  EXPECT_EQ(std::find(names.begin(), names.end(), behind), names.end()) << job["stages"];
  for (const char* stage : {"the scene's points", "the scene's points (waited)", "align depth to the scene's points"})
    EXPECT_EQ(std::find(names.begin(), names.end(), stage), names.end()) << job["stages"];
}

TEST(Serve, OrbitVideoAndEvaluationReportOfAServedPly) {
  RunningServer s(room_options());
  ASSERT_EQ(s.client->Post("/api/edit", edit_form("view_001", view_mask_bytes("view_001")))->status, 202);
  const json edit = s.finished_job();
  ASSERT_EQ(edit["state"], "done") << edit;
  const std::string ply = edit["result"]["ply"];

  auto r = s.client->Post("/api/video", httplib::Params{{"ply", ply}});
  ASSERT_EQ(r->status, 202) << r->body;
  const json video = s.finished_job();
  if (ffmpeg_available()) {
    ASSERT_EQ(video["state"], "done") << video;
    EXPECT_EQ(video["result"]["frames"], 48);
    const auto mp4 = s.client->Get(video["result"]["video"].get<std::string>());
    ASSERT_EQ(mp4->status, 200);
    EXPECT_EQ(mp4->get_header_value("Content-Type"), "video/mp4");
    EXPECT_EQ(mp4->body.substr(4, 4), "ftyp");
  } else {  // e.g. a GPU machine that has no ffmpeg: the job says what is missing
    EXPECT_EQ(video["state"], "failed") << video;
    EXPECT_NE(video.dump().find("ffmpeg is not installed"), std::string::npos) << video;
  }

  r = s.client->Post("/api/eval", httplib::Params{{"ply", edit["result"]["spz"].get<std::string>()}});  // as the page asks
  ASSERT_EQ(r->status, 202) << r->body;
  const json eval = s.finished_job();
  ASSERT_EQ(eval["state"], "done") << eval;
  EXPECT_TRUE(eval["result"]["mean"]["masked_psnr"].is_number()) << eval;
  const auto report = s.client->Get(eval["result"]["report"].get<std::string>());
  ASSERT_EQ(report->status, 200);
  EXPECT_NE(report->body.find("sheets/test_000.png"), std::string::npos);
  EXPECT_EQ(s.client->Get("/api/jobs/" + std::to_string(eval["id"].get<int>()) + "/eval/sheets/test_000.png")->status,
            200);

  // Only PLYs the server serves.
  for (const char* bad : {"/etc/passwd", "/api/plys/0", "/api/jobs/99/gaussians.ply", "../gaussians.ply"}) {
    r = s.client->Post("/api/video", httplib::Params{{"ply", bad}});
    EXPECT_EQ(r->status, 400) << bad;
    EXPECT_EQ(json::parse(r->body)["error"],
              std::string("ply must be the URL of a PLY this server serves, not '") + bad + "'");
  }
}

// Splats alone (serve --splats FILE): a box removes the object and fills the hole; the result
// can be filled again with a stroke on a camera; bad regions are refused with the reason.
// A small synthetic room with its splats (scene.ply) and the object's bounds, made once.
const fs::path& fill_room() {
  static const fs::path dir = [] {
    synth::SynthOptions so;
    so.views = 4;
    so.test_views = 1;
    so.width = 48;
    so.height = 40;
    so.object = synth::ObjectSource::procedural;
    const fs::path d = test::temp_dir("serve-fill") / "room";
    synth::SynthWriteOptions wo;
    wo.save_gaussians = true;
    wo.write_depth = false;
    synth::write_synth_scene(synth::generate_scene(so, 7), d, wo);
    return d;
  }();
  return dir;
}

// The form's box around fill_room's object: its centre, 2.2 times its radius on each side.
std::string fill_room_box() {
  const json bounds = json::parse(test::file_bytes(fill_room() / "synth.json"))["object_bounds"];
  const double r = 2.2 * bounds["radius"].get<double>();
  return fmt::format("{},{},{},{},{},{}", bounds["centre"][0].get<double>(), bounds["centre"][1].get<double>(),
                     bounds["centre"][2].get<double>(), r, r, r);
}

TEST(Serve, FillOnSplatsAlone) {
  const fs::path& dir = fill_room();
  ServeOptions o;
  o.plys = {dir / "scene.ply"};
  o.height = 40;
  o.views = 2;
  o.out = test::temp_dir("serve-fill-out");
  RunningServer s(o);
  EXPECT_TRUE(json::parse(s.client->Get("/api/info")->body)["filling"]);
  const std::string box = fill_room_box();
  auto r1 = s.client->Post("/api/fill", httplib::MultipartFormDataItems{{"ply", "/api/plys/0", "", ""}, {"box", box, "", ""}});
  ASSERT_EQ(r1->status, 202) << r1->body;
  json job = s.finished_job();
  ASSERT_EQ(job["state"], "done") << job;
  EXPECT_EQ(job["kind"], "fill");
  EXPECT_GT(job["result"]["fill"]["removed"].get<int>(), 0);
  EXPECT_GT(job["result"]["fill"]["added"].get<int>(), 0);
  const std::string filled = job["result"]["splats"];
  const auto report = s.client->Get(job["result"]["fill"]["report"].get<std::string>());
  ASSERT_EQ(report->status, 200);
  EXPECT_EQ(json::parse(report->body)["splats"]["removed"], job["result"]["fill"]["removed"]);
  const size_t output = json::parse(report->body)["splats"]["output"];
  EXPECT_EQ(read_splats(s.out / "jobs" / std::to_string(job["id"].get<int>()) / "gaussians.ply").size(), output);

  // Again on the result, with a stroke over the view of the first camera: the object's mask there.
  const std::vector<NamedCamera> cameras = read_camera_json(dir / "cameras.json");
  const NamedCamera& view = cameras.back();
  write_camera_json(o.out / "one.json", {view});
  const std::string camera = test::file_bytes(o.out / "one.json");
  const std::string mask = test::file_bytes(dir / "images_4" / "label" / (view.name + ".png"));
  auto r2 = s.client->Post("/api/fill", httplib::MultipartFormDataItems{
      {"ply", filled, "", ""}, {"camera", camera, "", ""}, {"mask", mask, "mask.png", "image/png"}});
  ASSERT_EQ(r2->status, 202) << r2->body;
  job = s.finished_job();
  EXPECT_EQ(job["state"], "done") << job;

  // The stroke with an inpainted picture of its view as the reference: the new splats take its
  // colours (magenta, which the room has nowhere).
  const int vw = view.camera.K.width, vh = view.camera.K.height;
  Image magenta(vw, vh, 3, 0.f);
  for (int y = 0; y < vh; ++y)
    for (int x = 0; x < vw; ++x) magenta.at(y, x, 0) = magenta.at(y, x, 2) = 1.f;
  write_png(o.out / "magenta.png", magenta);
  // The box again with the patch inpainter (the page's other choice): its fill.json says so.
  auto patched = s.client->Post("/api/fill", httplib::MultipartFormDataItems{
      {"ply", "/api/plys/0", "", ""}, {"box", box, "", ""}, {"inpainter", "patch", "", ""}});
  ASSERT_EQ(patched->status, 202) << patched->body;
  job = s.finished_job();
  ASSERT_EQ(job["state"], "done") << job;
  EXPECT_EQ(json::parse(s.client->Get(job["result"]["fill"]["report"].get<std::string>())->body)["inpainter"], "patch");

  auto r3 = s.client->Post("/api/fill", httplib::MultipartFormDataItems{
      {"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""}, {"mask", mask, "mask.png", "image/png"},
      {"reference", test::file_bytes(o.out / "magenta.png"), "reference.png", "image/png"}});
  ASSERT_EQ(r3->status, 202) << r3->body;
  job = s.finished_job();
  ASSERT_EQ(job["state"], "done") << job;
  const SplatCloud with_reference = read_splats(s.out / "jobs" / std::to_string(job["id"].get<int>()) / "gaussians.ply");
  const size_t added = job["result"]["fill"]["added"];
  ASSERT_GT(added, 0u);
  int magenta_splats = 0;
  for (size_t i = with_reference.size() - added; i < with_reference.size(); ++i) {
    const float* dc = &with_reference.sh_dc[3 * i];
    magenta_splats += dc[0] > dc[1] + 1.f && dc[2] > dc[1] + 1.f;  // SH DC: (colour - 0.5) / 0.2821
  }
  EXPECT_GT(magenta_splats, static_cast<int>(added) / 2) << added;

  // A click on the object in that view: its splats selected at once (not a job), drawn as runs of
  // the view's pixels; Fill with the same click removes exactly those.
  const Image label = read_mask(dir / "images_4" / "label" / (view.name + ".png"));
  double cx = 0, cy = 0, n = 0;
  for (int y = 0; y < label.height; ++y)
    for (int x = 0; x < label.width; ++x)
      if (label.at(y, x) > 0.5f) cx += x + 0.5, cy += y + 0.5, ++n;
  ASSERT_GT(n, 0);
  const std::string click = fmt::format("{:.1f},{:.1f}", cx / n, cy / n);
  auto selected = s.client->Post("/api/select", httplib::MultipartFormDataItems{
      {"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""}, {"clicks", click, "", ""}});
  ASSERT_EQ(selected->status, 200) << selected->body;
  const json selection = json::parse(selected->body);
  EXPECT_GT(selection["selected"].get<int>(), 0);
  EXPECT_EQ(selection["width"], vw);
  int64_t pixels = 0, covered = 0;
  for (size_t k = 0; k < selection["runs"].size(); ++k) {
    covered += selection["runs"][k].get<int64_t>();
    if (k % 2) pixels += selection["runs"][k].get<int64_t>();
  }
  EXPECT_EQ(covered, static_cast<int64_t>(vw) * vh);
  EXPECT_EQ(pixels, selection["pixels"]);
  auto clicked_fill = s.client->Post("/api/fill", httplib::MultipartFormDataItems{
      {"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""}, {"clicks", click, "", ""}});
  ASSERT_EQ(clicked_fill->status, 202) << clicked_fill->body;
  job = s.finished_job();
  ASSERT_EQ(job["state"], "done") << job;
  EXPECT_EQ(job["result"]["fill"]["removed"], selection["selected"]);
  auto select = [&](httplib::MultipartFormDataItems items) { return s.client->Post("/api/select", items); };
  // The splats alone: read ahead of the clicks (the page does it when its click tool is chosen).
  auto ahead = select({{"ply", "/api/plys/0", "", ""}});
  ASSERT_EQ(ahead->status, 200) << ahead->body;
  EXPECT_EQ(json::parse(ahead->body)["total"], selection["total"]);
  EXPECT_EQ(error_of(select({{"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""}, {"clicks", "3;4", "", ""}})),
            "clicks: '3' is not a point: X,Y in pixels of the view's image (e.g. 512,300)");
  EXPECT_EQ(error_of(select({{"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""}, {"clicks", "-4,2", "", ""}})),
            fmt::format("the click (-4, 2) is outside view the page's view's image ({}x{})", vw, vh));
  EXPECT_EQ(error_of(select({{"ply", "/api/plys/0", "", ""}, {"clicks", click, "", ""}})),
            "send multipart/form-data with clicks, and view (a scene view's index) or ply and camera");
  EXPECT_EQ(error_of(select({{"view", "0", "", ""}, {"clicks", click, "", ""}})),
            "the server was started without --scene: no views to click on");

  auto post = [&](httplib::MultipartFormDataItems items) { return s.client->Post("/api/fill", items); };
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"box", "1,2", "", ""}})),
            "box '1,2': 2 numbers, expected 6 (centre, size) or 9 (centre, size, rotation in degrees)");
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}})),
            "give the region: box (cx,cy,cz,sx,sy,sz[,rx,ry,rz]), or camera and mask or clicks");
  EXPECT_EQ(error_of(post({{"ply", "/etc/passwd", "", ""}, {"box", box, "", ""}})),
            "ply must be the URL of splats this server serves, not '/etc/passwd'");
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""},
                           {"mask", test::file_bytes(dir / "images_4" / "label" / "test_000.png").substr(0, 10), "m.png", ""}})),
            "mask: not a PNG or JPEG image");
  write_png(o.out / "small.png", Image(10, 10, 1, 1.f));
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""},
                           {"mask", test::file_bytes(o.out / "small.png"), "m.png", ""}})),
            fmt::format("mask: 10x10 pixels, but the camera is {}x{}", view.camera.K.width, view.camera.K.height));
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""}, {"mask", mask, "m.png", ""},
                           {"reference", test::file_bytes(o.out / "small.png"), "r.png", ""}})),
            fmt::format("reference: 10x10 pixels, but the view on screen is {}x{} (save view and mask, paint the view, "
                        "keep the camera still)",
                        vw, vh));
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"camera", camera, "", ""}, {"mask", mask, "m.png", ""},
                           {"reference", test::png_header(4000, 4000), "r.png", ""}})),
            fmt::format("reference: 4000x4000 pixels, more than this server decodes for the view on screen ({}x{}: at "
                        "most 4 times its pixels)",
                        vw, vh));
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"box", box, "", ""}, {"inpainter", "lama", "", ""}})),
            "inpainter: lama needs LaMa in the cache (instainpaint models get big-lama, then serve again) or serve "
            "--inpainter FILE");
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"box", box, "", ""}, {"inpainter", "sd", "", ""}})),
            "inpainter: unknown 2D inpainter 'sd' (telea, ns or patch)");
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"box", box, "", ""},
                           {"reference", test::file_bytes(o.out / "magenta.png"), "r.png", ""}})),
            "reference: only with a painted region (camera and mask); a box's reference view is the fill's choice");
  EXPECT_EQ(error_of(post({{"ply", "/api/plys/0", "", ""}, {"camera", "{", "", ""},
                           {"mask", mask, "m.png", ""}})).rfind("camera: ", 0), 0u);
}

// serve --inpainter with a LaMa file (the small fixture of tests/inpaint): /api/info names it, and
// a Fill without a reference has its hole painted by it, which the job's answer and fill.json say.
TEST(Serve, FillPaintedByTheServersLama) {
  const fs::path& dir = fill_room();
  ServeOptions o;
  o.plys = {dir / "scene.ply"};
  o.height = 40;
  o.views = 2;
  o.out = test::temp_dir("serve-lama-out");
  o.inpainter = inpainter_from_name("tests/inpaint/fixture/lama-small/models/best.ckpt");
  RunningServer s(o);
  const json info = json::parse(s.client->Get("/api/info")->body);
  EXPECT_EQ(info["inpainter"]["name"], "lama");
  EXPECT_EQ(info["inpainter"]["network"], "LaMa FFC-ResNet (ngf 8, 2 blocks)");
  const std::string box = fill_room_box();
  for (const std::string asked : {"", "lama"}) {  // the server's by default, and by name
    httplib::MultipartFormDataItems form{{"ply", "/api/plys/0", "", ""}, {"box", box, "", ""}};
    if (!asked.empty()) form.push_back({"inpainter", asked, "", ""});
    auto posted = s.client->Post("/api/fill", form);
    ASSERT_EQ(posted->status, 202) << posted->body;
    const json job = s.finished_job();
    ASSERT_EQ(job["state"], "done") << job;
    EXPECT_EQ(job["result"]["fill"]["inpainter"], "lama");
    const json report = json::parse(s.client->Get(job["result"]["fill"]["report"].get<std::string>())->body);
    EXPECT_EQ(report["inpainter"], "lama");
    EXPECT_EQ(report["inpainter_file"]["sha256"].get<std::string>().size(), 64u);
  }
}

TEST(Serve, WithoutASceneItOnlyShows) {
  ServeOptions o;
  o.out = test::temp_dir("serve-no-scene");
  RunningServer s(o, nullptr);
  const json info = json::parse(s.client->Get("/api/info")->body);
  EXPECT_TRUE(info["scene"].is_null());
  EXPECT_FALSE(info["editing"]);
  const auto r = s.client->Post("/api/edit", edit_form("view_000", "x"));
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(json::parse(r->body)["error"], "the server was started without --scene: nothing to edit");
}

}  // namespace
}  // namespace ii
