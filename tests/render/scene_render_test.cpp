// End-to-end camera conventions: fern's COLMAP points, splatted from the scene's own
// cameras (read by load_scene), must land where the photo shows them.
#include <gtest/gtest.h>

#include "data/scene.h"
#include "io/colmap.h"
#include "render/rasterizer.h"
#include "test_support.h"

namespace ii {
namespace {

TEST(SceneRender, FernPointsMatchThePhoto) {
  II_REQUIRE_SHARED(dir, "data/fern");
  SceneOptions opts;
  opts.format = "llff";
  opts.image_folder = "images_8";
  const Scene scene = load_scene(dir, opts);
  const ColmapModel model = read_colmap_model(dir / "sparse" / "0");
  ASSERT_GT(model.points.size(), 1000u);

  const int64_t n = static_cast<int64_t>(model.points.size());
  GaussianSet g;
  g.means = torch::empty({n, 3}, torch::kFloat64);
  g.colors = torch::empty({n, 3}, torch::kFloat64);
  int64_t i = 0;
  for (const auto& [id, p] : model.points) {
    for (int c = 0; c < 3; ++c) {
      g.means[i][c] = p.xyz[c];
      g.colors[i][c] = p.rgb[c] / 255.0;
    }
    ++i;
  }
  g.quats = torch::tensor({1.0, 0.0, 0.0, 0.0}, torch::kFloat64).repeat({n, 1});
  g.scales = torch::full({n, 3}, 0.1, torch::kFloat64);
  g.opacities = torch::full({n}, 0.95, torch::kFloat64);

  for (const size_t v : {size_t(0), scene.views.size() / 2}) {
    const View& view = scene.views[v];
    SCOPED_TRACE(view.name);
    RenderCamera cam;
    cam.camera = view.camera;
    const RenderOutput out = render(g, cam);
    const Image photo = load_view_image(view);
    ASSERT_EQ(photo.width, out.rgb.size(1));
    ASSERT_EQ(photo.height, out.rgb.size(0));
    const torch::Tensor real =
        torch::from_blob(const_cast<float*>(photo.pixels.data()), {photo.height, photo.width, 3}, torch::kFloat32)
            .to(torch::kFloat64);
    const torch::Tensor covered = (out.alpha.squeeze(2) > 0.8);
    const double coverage = covered.to(torch::kFloat64).mean().item<double>();
    EXPECT_GT(coverage, 0.1) << "the points should cover much of the view";
    // Pearson correlation of brightness over covered pixels: the right alignment must beat
    // the photo turned upside down or mirrored (what a wrong axis convention would give).
    auto correlation = [&](const torch::Tensor& image) {
      const torch::Tensor a = out.rgb.mean(2).index({covered}), b = image.mean(2).index({covered});
      const torch::Tensor da = a - a.mean(), db = b - b.mean();
      return ((da * db).sum() / (da.norm() * db.norm())).item<double>();
    };
    const double right = correlation(real), flipped = correlation(real.flip({0})),
                 mirrored = correlation(real.flip({1}));
    EXPECT_GT(right, 0.4);
    EXPECT_GT(right, flipped + 0.25);
    EXPECT_GT(right, mirrored + 0.25);
    std::printf("%s: coverage %.2f, brightness correlation %.3f (flipped %.3f, mirrored %.3f)\n", view.name.c_str(),
                coverage, right, flipped, mirrored);
  }
}

}  // namespace
}  // namespace ii
