#include "model/model_input.h"

#include <deque>
#include <mutex>

#include "common/error.h"
#include "common/parallel.h"

namespace ii {

namespace {

torch::Tensor from_vector(const std::vector<float>& v, at::IntArrayRef shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32).clone();
}

}  // namespace

namespace {

struct RayTensors {
  std::vector<Camera> cameras;
  torch::Tensor rays_o, rays_d, rays_d_un, plucker;
};

bool same_cameras(const std::vector<Camera>& a, const std::vector<Camera>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    const Intrinsics &p = a[i].K, &q = b[i].K;
    if (p.width != q.width || p.height != q.height || p.fx != q.fx || p.fy != q.fy || p.cx != q.cx || p.cy != q.cy ||
        a[i].c2w != b[i].c2w)
      return false;
  }
  return true;
}

std::mutex recent_mutex;
std::deque<RayTensors> recent;  // the last two sets, newest first

}  // namespace

void compute_ray_tensors(const std::vector<Camera>& cameras, torch::Tensor& rays_o,
                         torch::Tensor& rays_d, torch::Tensor& rays_d_un, torch::Tensor& plucker) {
  {
    std::lock_guard<std::mutex> lock(recent_mutex);
    for (const RayTensors& r : recent)
      if (same_cameras(r.cameras, cameras)) {
        rays_o = r.rays_o, rays_d = r.rays_d, rays_d_un = r.rays_d_un, plucker = r.plucker;
        return;
      }
  }
  // The cameras' rays side by side (a few tens of ms a view at 512 high).
  std::vector<Rays> rays(cameras.size());
  std::vector<std::vector<float>> pluckers(cameras.size());
  parallel_dynamic(static_cast<int64_t>(cameras.size()), thread_plan().cores, [&](int64_t i) {
    rays[static_cast<size_t>(i)] = compute_rays(cameras[static_cast<size_t>(i)]);
    pluckers[static_cast<size_t>(i)] = plucker_chw(rays[static_cast<size_t>(i)]);
  });
  std::vector<torch::Tensor> o, d, du, pl;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const Rays& r = rays[i];
    const int64_t H = r.height, W = r.width;
    o.push_back(from_vector(r.origin, {H, W, 3}));
    d.push_back(from_vector(r.dir, {H, W, 3}));
    du.push_back(from_vector(r.dir_unnorm, {H, W, 3}));
    pl.push_back(from_vector(pluckers[i], {6, H, W}));
  }
  rays_o = torch::stack(o);
  rays_d = torch::stack(d);
  rays_d_un = torch::stack(du);
  plucker = torch::stack(pl);
  std::lock_guard<std::mutex> lock(recent_mutex);
  recent.push_front({cameras, rays_o, rays_d, rays_d_un, plucker});
  if (recent.size() > 2) recent.pop_back();
}

ModelInput build_model_input(const std::vector<PreparedView>& views,
                             const PoseNormalization& normalization) {
  if (views.empty()) fail("no input views");
  const int H = views[0].rgb.height, W = views[0].rgb.width;
  ModelInput in;
  std::vector<torch::Tensor> images;
  std::vector<torch::Tensor> cams;
  for (size_t v = 0; v < views.size(); ++v) {
    const PreparedView& pv = views[v];
    if (pv.rgb.width != W || pv.rgb.height != H)
      fail("view {} is {}x{} after preprocessing, the reference is {}x{}: all input views must "
           "have the same size", pv.name, pv.rgb.width, pv.rgb.height, W, H);
    const bool is_reference = v == 0;
    if (!is_reference && !pv.mask)
      fail("view {} has no object mask: every input view except the reference needs one", pv.name);
    torch::Tensor rgb = from_vector(pv.rgb.pixels, {H, W, 3}).permute({2, 0, 1}) * 2.0 - 1.0;
    torch::Tensor mask = is_reference ? torch::zeros({1, H, W})
                                      : from_vector(pv.mask->pixels, {1, H, W});
    images.push_back(torch::cat({rgb * (1.0 - mask), mask}, 0));

    const Camera cam = normalization.apply(pv.camera);
    in.view_cameras.push_back(cam);
    const auto vec = cam.official_vector();
    cams.push_back(torch::from_blob(const_cast<float*>(vec.data()), {20}, torch::kFloat32).clone());
    in.names.push_back(pv.name);
  }
  in.images = torch::stack(images).contiguous();
  in.cameras = torch::stack(cams);
  compute_ray_tensors(in.view_cameras, in.rays_o, in.rays_d, in.rays_d_un, in.plucker);
  return in;
}

}  // namespace ii
