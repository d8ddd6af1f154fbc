#pragma once
// LaMa as the reference's 2D inpainter (data/inpaint2d.h's LearnedInpainter): the region painted
// in a crop around it, at most `work_side` pixels on a side (LaMa was trained on 256-pixel crops
// and its Fourier units see the whole crop: a large photo with a small object costs little, and
// a large region is painted at a size the network knows), then put back at the photo's size,
// inside the region only.
#include <filesystem>
#include <memory>
#include <string>

#include "data/inpaint2d.h"
#include "inpaint/lama.h"

namespace ii {

struct LamaOptions {
  // Around the region's box: this fraction of its larger side on each side (the context LaMa
  // paints from), at least `min_margin` pixels.
  double margin = 0.5;
  int min_margin = 32;
  int work_side = 512;  // the crop brought down to at most this many pixels on its larger side
  // The whole photo at its size instead (as the reference's bin/predict.py paints).
  bool whole_photo = false;
  // auto (bf16 on a GPU and on CPUs with native bf16: AVX512-BF16, AMX), fp32 or bf16.
  std::string precision = "auto";
  // auto (a GPU when LibTorch sees one), cpu, cuda, cuda:N.
  std::string device = "auto";
};

class LamaInpainter : public LearnedInpainter {
 public:
  LamaInpainter(Lama lama, LamaOptions options = {});
  Image paint(const Image& rgb, const Image& mask) const override;
  std::string name() const override { return "lama"; }
  nlohmann::json describe() const override;  // name, network, file, sha256

 private:
  Lama lama_;
  LamaOptions options_;
  nlohmann::json file_;  // models/cache.h model_file_description
};

// The file as the reference's inpainter: `name` "telea", "ns" or "patch" is that classical
// method; anything else is a LaMa file (an Error naming it when it is none).
Inpainter inpainter_from_name(const std::string& name, const LamaOptions& options = {});
// The --inpainter of a command: `flag` when given, else $INSTAINPAINT_INPAINTER, else "auto": the
// cache's LaMa when there is one (instainpaint models get big-lama), else `fallback`. A catalogue
// name ("big-lama") is its cached file.
Inpainter inpainter_from_flag(const std::string& flag, const std::string& fallback, const LamaOptions& options = {});

}  // namespace ii
