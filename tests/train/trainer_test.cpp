// The training step: the two-phase backward of spec §6.4 equals a joint backward, block
// recomputation gives the same gradients, the weight-norm parametrisation, and a short run
// that overfits one sample.
#include <gtest/gtest.h>

#include "gaussians/gaussians.h"
#include "render/rasterizer.h"
#include "test_support.h"
#include "train/trainer.h"
#include "train_test_util.h"

namespace ii {
namespace {

TrainerOptions options_for_test(int64_t steps = 100, double lr = 1e-3) {
  TrainerOptions o;
  o.schedule.total_steps = steps;
  o.schedule.warmup_steps = 0;
  o.schedule.peak_lr = lr;
  o.loss.perceptual = "ssim";
  return o;
}

double max_relative_difference(const std::vector<torch::Tensor>& a, const std::vector<torch::Tensor>& b) {
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!a[i].grad().defined() && !b[i].grad().defined()) continue;
    const torch::Tensor ga = a[i].grad(), gb = b[i].grad();
    const double scale = std::max(ga.abs().max().item<double>(), 1e-12);
    worst = std::max(worst, (ga - gb).abs().max().item<double>() / scale);
  }
  return worst;
}

TEST(TrainableParameters, OfficialWeightNormNamesAndSameWeights) {
  Network net = test::seeded_network(1);
  const TrainableParameters params(net);
  int g = 0, v = 0;
  for (const std::string& n : params.names()) {
    g += n.size() > 9 && n.compare(n.size() - 9, 9, ".weight_g") == 0;
    v += n.size() > 9 && n.compare(n.size() - 9, 9, ".weight_v") == 0;
  }
  // 4 Linears per block, 2 per head (upsampler depth 1).
  EXPECT_EQ(g, 4 * net.config().blocks + 2 * 5);
  EXPECT_EQ(v, g);
  const std::vector<torch::Tensor> w = params.network_weights();
  for (size_t i = 0; i < w.size(); ++i)
    EXPECT_TRUE(torch::allclose(w[i], net.named_parameters()[i].second, 1e-5, 1e-7)) << net.named_parameters()[i].first;
}

// The trainer's loss on `batch` with one graph from the weights to every render, its
// gradients left in the returned parameters.
// Input view v's own Gaussians of one sample's maps (1, V, C, H, W) at its camera: the MSE in
// [-1, 1] against its image outside its mask.
torch::Tensor own_view_mse_by_hand(const GaussianMaps& one, const TrainingSample& s, int64_t v) {
  const torch::Tensor rgb =
      render(gaussians_from_maps(narrowed(one, 1, v)), RenderCamera{s.input.view_cameras[static_cast<size_t>(v)]}).rgb;
  const torch::Tensor pred = (rgb * 2 - 1).clamp(-1, 1).permute({2, 0, 1});
  const torch::Tensor image = s.input.images[v];
  const torch::Tensor outside = 1 - image[3];
  return ((pred - image.narrow(0, 0, 3)).pow(2) * outside).sum() / (3 * outside.sum());
}

TrainableParameters joint_backward(const std::vector<TrainingSample>& batch, const LossOptions& options,
                                   uint64_t network_seed) {
  Network net = test::seeded_network(network_seed);
  TrainableParameters params(net);
  params.bind(net);
  ImageLoss loss(options);
  std::vector<torch::Tensor> images, plucker, rays_o, rays_d_un;
  for (const auto& s : batch) {
    images.push_back(s.input.images);
    plucker.push_back(s.input.plucker);
    rays_o.push_back(s.input.rays_o);
    rays_d_un.push_back(s.input.rays_d_un);
  }
  const GaussianMaps maps = net.forward(torch::stack(images), torch::stack(plucker), torch::stack(rays_o),
                                        torch::stack(rays_d_un))
                                .gaussians;
  const auto B = static_cast<int64_t>(batch.size());
  torch::Tensor total = torch::zeros({}), image_total = torch::zeros({}), own_total = torch::zeros({});
  int64_t targets = 0;
  for (int64_t b = 0; b < B; ++b) {
    if (batch[b].input_depths.defined())
      total = total + depth_loss(maps.depth[b], batch[b].input_depths) * (options.depth_weight / B);
    const GaussianMaps one = narrowed(maps, 0, b);
    const int64_t V = one.xyz.size(1);
    const GaussianSet set = gaussians_from_maps(one);
    for (size_t m = 0; m < batch[b].target_cameras.size(); ++m, ++targets) {
      const torch::Tensor rgb = render(set, RenderCamera{batch[b].target_cameras[m]}).rgb;
      const torch::Tensor pred = (rgb * 2 - 1).clamp(-1, 1).permute({2, 0, 1}).unsqueeze(0);
      image_total = image_total + loss(pred, batch[b].target_images[static_cast<int64_t>(m)].unsqueeze(0)).total;
    }
    for (int64_t v = 0; options.own_view_weight > 0 && v < V; ++v)
      own_total = own_total + own_view_mse_by_hand(one, batch[b], v) * (options.own_view_weight / static_cast<double>(V * B));
  }
  (total + image_total / static_cast<double>(targets) + own_total).backward();
  return params;
}

TEST(Trainer, TwoPhaseBackwardEqualsJointBackward) {
  const std::vector<TrainingSample> batch = test::tiny_batch(3, 0, 2);
  Trainer trainer(test::seeded_network(2), options_for_test());
  trainer.compute_gradients(batch);
  const TrainableParameters params = joint_backward(batch, options_for_test().loss, 2);
  EXPECT_LT(max_relative_difference(trainer.parameters().tensors(), params.tensors()), 1e-4);
  EXPECT_GT(params.tensors()[0].grad().abs().max().item<double>(), 0);  // the patch embedding learns
}

// Depth for the first sample only (the second stands for a real scene without depth maps),
// with unknown (0) pixels; seeded.
void give_the_first_sample_depth(std::vector<TrainingSample>& batch) {
  const torch::Tensor& images = batch[0].input.images;
  torch::manual_seed(5);
  batch[0].input_depths = torch::rand({images.size(0), 1, images.size(2), images.size(3)}) * 3 + 0.5;
  batch[0].input_depths.select(3, 0).zero_();
}

TEST(Trainer, DepthLossEntersTheTwoPhaseBackward) {
  std::vector<TrainingSample> batch = test::tiny_batch(3, 0, 2);
  give_the_first_sample_depth(batch);
  TrainerOptions o = options_for_test();
  o.loss.depth_weight = 0.7;
  Trainer trainer(test::seeded_network(2), o);
  const StepStats stats = trainer.compute_gradients(batch);
  const TrainableParameters params = joint_backward(batch, o.loss, 2);
  EXPECT_LT(max_relative_difference(trainer.parameters().tensors(), params.tensors()), 1e-4);
  EXPECT_GT(stats.depth, 0);
  // The same batch without the depth term gives other gradients and a smaller loss.
  Trainer image_only(test::seeded_network(2), options_for_test());
  const StepStats plain = image_only.compute_gradients(batch);
  EXPECT_NEAR(stats.loss - plain.loss, 0.7 * stats.depth / 2, 1e-6);
  EXPECT_GT(max_relative_difference(trainer.parameters().tensors(), image_only.parameters().tensors()), 1e-3);
  // evaluate() reports the depth error of samples that have depth maps only.
  EXPECT_TRUE(trainer.evaluate(batch[0]).depth.has_value());
  EXPECT_FALSE(trainer.evaluate(batch[1]).depth.has_value());
}

// The own-view term enters the two-phase backward as a joint backward's would, and its weighted
// mean is the loss's share.
TEST(Trainer, OwnViewTermEntersTheTwoPhaseBackward) {
  std::vector<TrainingSample> batch = test::tiny_batch(3, 0, 2);
  give_the_first_sample_depth(batch);
  TrainerOptions o = options_for_test();
  o.loss.depth_weight = 0.3;
  o.loss.own_view_weight = 0.5;
  Trainer trainer(test::seeded_network(2), o);
  const StepStats stats = trainer.compute_gradients(batch);
  const TrainableParameters params = joint_backward(batch, o.loss, 2);
  EXPECT_LT(max_relative_difference(trainer.parameters().tensors(), params.tensors()), 1e-4);
  EXPECT_GT(stats.own_view, 0);
  // Without the term: other gradients, a loss smaller by the weighted term, no term logged.
  TrainerOptions no_own = o;
  no_own.loss.own_view_weight = 0;
  Trainer images_only(test::seeded_network(2), no_own);
  const StepStats no_own_stats = images_only.compute_gradients(batch);
  EXPECT_EQ(no_own_stats.own_view, 0);
  EXPECT_NEAR(stats.loss - no_own_stats.loss, 0.5 * stats.own_view, 1e-6);
  EXPECT_GT(max_relative_difference(trainer.parameters().tensors(), images_only.parameters().tensors()), 1e-3);
  // evaluate() reports the own views' PSNR, the mean over the views (images mapped to [0, 1]).
  const EvalStats e = trainer.evaluate(batch[0]);
  Network net = test::seeded_network(2);
  torch::NoGradGuard no_grad;
  const TrainingSample& s = batch[0];
  const GaussianMaps maps =
      net.forward(s.input.images.unsqueeze(0), s.input.plucker.unsqueeze(0), s.input.rays_o.unsqueeze(0),
                  s.input.rays_d_un.unsqueeze(0))
          .gaussians;
  double psnr = 0;
  for (int64_t v = 0; v < 4; ++v) psnr += 10 * std::log10(4 / own_view_mse_by_hand(maps, s, v).item<double>()) / 4;
  EXPECT_NEAR(e.own_psnr, psnr, 1e-3);
}

TEST(DepthLoss, LogL1OverKnownPixelsWithItsGradient) {
  const torch::Tensor target = torch::tensor({2.0, 0.0, 4.0, 1.0}, torch::kFloat64);
  const torch::Tensor predicted = torch::tensor({1.0, 5.0, 4.0, 3.0}, torch::kFloat64).requires_grad_(true);
  const torch::Tensor loss = depth_loss(predicted, target);
  EXPECT_NEAR(loss.item<double>(), (std::log(2.0) + 0 + std::log(3.0)) / 3, 1e-12);
  loss.backward();
  // d/dp |log p − log t| = sign(log p − log t) / p, over the 3 known pixels; none at target 0.
  const torch::Tensor expected = torch::tensor({-1.0 / 3, 0.0, 0.0, 1.0 / 9}, torch::kFloat64);
  EXPECT_TRUE(torch::allclose(predicted.grad(), expected, 1e-12, 1e-12)) << predicted.grad();
  EXPECT_EQ(depth_loss(predicted, torch::zeros({4}, torch::kFloat64)).item<double>(), 0.0);
  EXPECT_EQ(test::error_message([&] { depth_loss(predicted, torch::ones({3})); }),
            "depth loss: prediction [4] and target [3] differ in shape");
}

TEST(Trainer, BlockRecomputationGivesSameGradients) {
  const std::vector<TrainingSample> batch = test::tiny_batch(4, 0, 1);
  Trainer plain(test::seeded_network(3), options_for_test());
  TrainerOptions o = options_for_test();
  o.checkpoint_blocks = true;
  Trainer recomputed(test::seeded_network(3), o);
  const StepStats a = plain.compute_gradients(batch), b = recomputed.compute_gradients(batch);
  EXPECT_DOUBLE_EQ(a.loss, b.loss);
  EXPECT_LT(max_relative_difference(plain.parameters().tensors(), recomputed.parameters().tensors()), 1e-5);
}

TEST(Network, RecomputedBlocksAreInTheGraph) {
  Network net = test::seeded_network(3);
  net.set_requires_grad(true);
  net.set_activation_checkpointing(true);
  const TrainingSample s = test::tiny_sample(1, 0);
  const NetworkOutput out = net.forward(s.input.images.unsqueeze(0), s.input.plucker.unsqueeze(0),
                                        s.input.rays_o.unsqueeze(0), s.input.rays_d_un.unsqueeze(0));
  ASSERT_TRUE(out.transformer_tokens.grad_fn());
  EXPECT_NE(out.transformer_tokens.grad_fn()->name().find("RecomputedBlock"), std::string::npos)
      << out.transformer_tokens.grad_fn()->name();
}

TEST(Trainer, ShortRunOverfitsOneSample) {
  const std::vector<TrainingSample> batch = test::tiny_batch(5, 0, 1);
  Trainer trainer(test::seeded_network(4), options_for_test(40, 2e-3));
  const double first = trainer.step(batch).loss;
  StepStats last;
  for (int i = 1; i < 40; ++i) last = trainer.step(batch);
  EXPECT_EQ(last.step, 40);
  EXPECT_TRUE(std::isfinite(last.grad_norm));
  EXPECT_LT(last.loss, 0.6 * first) << "first " << first << " last " << last.loss;
  // Held-out evaluation of the same sample agrees with the training loss's scale.
  torch::Tensor renders;
  const EvalStats e = trainer.evaluate(batch[0], &renders);
  EXPECT_EQ(e.targets, 2);
  EXPECT_EQ(renders.sizes(), (std::vector<int64_t>{2, 3, 32, 32}));
  EXPECT_LT(e.loss, first);
  EXPECT_GT(e.psnr, 0);
}

TEST(Trainer, Bf16ForwardGivesFiniteGradients) {
  TrainerOptions o = options_for_test();
  o.precision = Precision::BFloat16;
  Trainer trainer(test::seeded_network(5), o);
  const StepStats s = trainer.step(test::tiny_batch(6, 0, 1));
  EXPECT_TRUE(std::isfinite(s.loss));
  EXPECT_EQ(s.nonfinite_tensors, 0);
  EXPECT_GT(s.grad_norm, 0);
}

TEST(Trainer, RejectsMismatchedSamples) {
  Trainer trainer(test::seeded_network(6), options_for_test());
  std::vector<TrainingSample> batch = test::tiny_batch(7, 0, 1);
  batch[0].target_cameras.pop_back();
  EXPECT_EQ(test::error_message([&] { trainer.step(batch); }), "training sample from tiny_0: 2 target images for 1 cameras");
}

}  // namespace
}  // namespace ii
