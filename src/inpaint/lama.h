#pragma once
// LaMa (github.com/advimman/lama, Suvorov et al. 2022): its FFC-ResNet generator, read from the
// checkpoint its authors publish (big-lama/models/best.ckpt, PyTorch Lightning's file: the
// generator's weights are taken, the rest is left), or lama-cleaner's and IOPaint's big-lama.pt
// (the generator traced to TorchScript: its modules' attributes read, its code never run), and
// run on LibTorch. The architecture is read
// from the weights' shapes (the width, the downsamplings, the residual blocks, the share of the
// channels that go through the Fourier units); the output activation is big-lama's sigmoid.
// The file is read by the project's restricted pickle reader: nothing in it is executed.
//
// Inference follows the reference's bin/predict.py: the photo (RGB in [0, 1]) padded to a
// multiple of 8 by symmetric reflection, the photo with its region blanked and the region's mask
// given to the generator, its picture put into the region, the padding cut. Equal to the
// reference code within 1e-4 (tests/inpaint).
//
//   const Lama lama = Lama::load("big-lama/models/best.ckpt");
//   const Image painted = lama.inpaint(photo, mask);  // photo (H, W, 3), mask (H, W) > 0.5 = region
#include <filesystem>
#include <memory>
#include <string>

#include "common/torch.h"
#include "io/image.h"

namespace ii {

namespace lama {
struct Generator;
}

class Lama {
 public:
  // Errors name the file and the key: not a LaMa generator, a tensor missing or of the wrong
  // shape, a truncated file, a layout this reader does not run (LaMa's local Fourier units).
  // `bf16`: the convolutions in bf16 (the Fourier transforms stay float): on a CPU with native
  // bf16 (AVX512-BF16, AMX) faster, and within 0.002 of float's pixels on the fixture.
  // `device`: where it runs (the photo goes there and back).
  static Lama load(const std::filesystem::path& file, bool bf16 = false, torch::Device device = torch::kCPU);
  bool bf16() const;

  // The photo with the region painted by the generator; the photo outside the region as it was.
  // photo: 3 channels in [0, 1]; mask: 1 channel at the photo's size, > 0.5 = the region.
  Image inpaint(const Image& photo, const Image& mask) const;
  // The generator on its input: (1, 4, H, W), H and W multiples of 8 (the blanked photo, the
  // mask) -> (1, 3, H, W) in [0, 1].
  torch::Tensor generate(const torch::Tensor& input) const;

  // "LaMa FFC-ResNet (ngf 64, 18 blocks)"
  std::string description() const;
  const std::filesystem::path& file() const { return file_; }

 private:
  std::shared_ptr<const lama::Generator> generator_;
  std::filesystem::path file_;
};

}  // namespace ii
