#pragma once
// LPIPS with random weights in torchvision's layout, for tests that need a scorer but not its
// trained values (the real backbone is the user's file).
#include <cmath>
#include <cstdint>
#include <vector>

#include <fmt/format.h>

#include "common/torch.h"
#include "eval/lpips.h"
#include "eval/weights.h"

namespace ii::test {

// Random weights with torchvision's `features` keys for `net`, scaled so that activations
// neither vanish nor explode.
inline WeightMap random_backbone(LpipsNet net, uint64_t seed) {
  torch::manual_seed(seed);
  struct L {
    int index;
    int64_t in, out, k;
  };
  const std::vector<L> layers =
      net == LpipsNet::vgg
          ? std::vector<L>{{0, 3, 64, 3},     {2, 64, 64, 3},    {5, 64, 128, 3},   {7, 128, 128, 3},
                           {10, 128, 256, 3}, {12, 256, 256, 3}, {14, 256, 256, 3}, {17, 256, 512, 3},
                           {19, 512, 512, 3}, {21, 512, 512, 3}, {24, 512, 512, 3}, {26, 512, 512, 3},
                           {28, 512, 512, 3}}
          : std::vector<L>{{0, 3, 64, 11}, {3, 64, 192, 5}, {6, 192, 384, 3}, {8, 384, 256, 3}, {10, 256, 256, 3}};
  WeightMap w;
  for (const L& l : layers) {
    w[fmt::format("features.{}.weight", l.index)] =
        torch::randn({l.out, l.in, l.k, l.k}) * std::sqrt(2.0 / (l.in * l.k * l.k));
    w[fmt::format("features.{}.bias", l.index)] = torch::randn({l.out}) * 0.01;
  }
  w["classifier.0.weight"] = torch::zeros({2, 2});  // other keys are ignored
  return w;
}

inline std::vector<torch::Tensor> random_heads(LpipsNet net) {
  std::vector<torch::Tensor> heads;
  for (int64_t c : lpips_stage_channels(net)) heads.push_back(torch::rand({1, c, 1, 1}) * 0.1);
  return heads;
}

}  // namespace ii::test
