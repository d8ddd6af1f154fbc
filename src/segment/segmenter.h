#pragma once
// A promptable segmentation network (SAM, MobileSAM) run natively from the files their authors
// publish: MobileSAM's mobile_sam.pt (TinyViT), SAM's sam_vit_b_01ec64.pth, sam_vit_l_0b3195.pth and
// sam_vit_h_4b8939.pth (ViT). A photo is encoded once; each prompt after that (points on and off
// the object, a box, the previous answer's mask) runs only the small decoder. The answers equal
// the reference code's SamPredictor (tests/segment: parity with fixtures it wrote).
//
//   const Segmenter segmenter = Segmenter::load("mobile_sam.pt");
//   const SegmenterImage photo = segmenter.encode(read_image_rgb("IMG_2707.JPG"));
//   SegmentPrompt prompt;
//   prompt.points = {{512, 300, true}};
//   const Segmentation s = segmenter.segment(photo, prompt);
//   const Image mask = s.mask(s.best());  // 0/1 at the photo's size
#include <array>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "camera/click.h"
#include "common/stage_times.h"
#include "common/torch.h"
#include "io/image.h"

namespace ii {

namespace sam {
struct Model;
}

struct SegmentPoint {
  double x = 0, y = 0;  // pixels of the photo (x right, y down)
  bool on_object = true;  // false: a point that is not the object
};

struct SegmentPrompt {
  std::vector<SegmentPoint> points;
  std::optional<std::array<double, 4>> box;  // x0, y0, x1, y1 in the photo's pixels
  // A previous answer's low-resolution logits (one mask, (S/4, S/4)), to refine.
  std::optional<torch::Tensor> previous;
  // Three masks of different extent (the part, the object, the whole) for an ambiguous prompt;
  // false: one mask.
  bool multimask = true;
};

struct Segmentation {
  torch::Tensor logits;   // (K, H, W) at the photo's size; > 0 is the object (see first)
  torch::Tensor scores;   // (K) the network's estimate of each mask's IoU
  torch::Tensor low_res;  // (K, S/4, S/4), for SegmentPrompt::previous
  // The index of logits' first mask: 0, or with segment(..., best_only) the best's (logits then
  // holds it alone: bringing the other two to the photo's size was most of a click's time).
  int first = 0;
  int best() const;       // the mask of the highest score
  Image mask(int k) const;  // 1 channel, 0/1; k one of the masks logits holds
};

// A photo encoded for the decoder: the image embedding and the sizes to map prompts and masks.
struct SegmenterImage {
  torch::Tensor embedding;  // (1, D, G, G)
  int width = 0, height = 0;              // the photo's
  int input_width = 0, input_height = 0;  // resized so that its longer side is the encoder's size
};

// Auto: bf16 products where the CPU has native bf16 (AVX-512 BF16, AMX), else float. Float is
// the reference code's arithmetic (the parity tests'); bf16 is faster and moves the logits by up
// to 5 % of their range (tests/segment).
enum class SegmenterPrecision { Auto, Float32, BFloat16 };
// "auto", "fp32" or "bf16" (the commands' --precision); another name is an Error.
SegmenterPrecision parse_segmenter_precision(const std::string& name);

class Segmenter {
 public:
  // Reads a SAM or MobileSAM checkpoint (.pt/.pth through the restricted reader, never executed;
  // or safetensors with the same keys). Errors name the file and the tensor.
  static Segmenter load(const std::filesystem::path& path, SegmenterPrecision precision = SegmenterPrecision::Auto);
  ~Segmenter();
  Segmenter(Segmenter&&) noexcept;
  Segmenter& operator=(Segmenter&&) noexcept;

  // "MobileSAM TinyViT (4 stages)", "SAM ViT (768 wide, 12 blocks, 12 heads)".
  const std::string& description() const;
  bool bf16() const;
  const std::filesystem::path& file() const { return file_; }
  // The file as records name it (models/cache.h model_file_description: file, sha256, "from"),
  // made at the first call and kept: a file outside the cache is hashed once, not at every click.
  const nlohmann::json& file_description() const;
  int image_size() const;  // the encoder's square input (1024 for the published models)

  // An RGB photo (values in [0,1], rounded to bytes as a decoded photo is).
  SegmenterImage encode(const Image& rgb) const;
  // The encoder's input for `rgb`: Pillow's bilinear resize, normalised, padded ((1, 3, S, S)).
  torch::Tensor encoder_input(const Image& rgb, int& input_width, int& input_height) const;
  // best_only: of several masks, only the best-scored brought to the photo's size (Segmentation::first).
  Segmentation segment(const SegmenterImage& image, const SegmentPrompt& prompt, bool best_only = false) const;

 private:
  Segmenter() = default;
  std::unique_ptr<sam::Model> model_;
  std::filesystem::path file_;
  struct FileDescription {
    std::once_flag once;
    nlohmann::json json;
  };
  std::shared_ptr<FileDescription> file_description_ = std::make_shared<FileDescription>();
};

// The mask of the object under clicks on a photo (pixel centres at +0.5, as camera/click.h's)
// and points that are not it: one click asks for SAM's three masks and keeps the best-scored,
// more points ask for one. An Error when the mask is empty.
struct ClickedMask {
  Image mask;  // 0/1 at the photo's size
  int chosen = 0;
  std::vector<double> scores;
  int64_t pixels = 0;
  nlohmann::json describe(const Segmenter& segmenter) const;  // file, network, precision, chosen, scores, pixels
};
ClickedMask mask_from_clicks(const Segmenter& segmenter, const Image& photo, const std::vector<Click>& clicks,
                             const std::vector<Click>& not_clicks, StageTimes* stages = nullptr);
// The same on a photo encoded before (a page's later clicks on the same view: the decoder alone).
ClickedMask mask_from_clicks(const Segmenter& segmenter, const SegmenterImage& photo, const std::vector<Click>& clicks,
                             const std::vector<Click>& not_clicks, StageTimes* stages = nullptr);
// A box around the object (camera/click.h), with or without clicks: one mask.
ClickedMask mask_from_prompt(const Segmenter& segmenter, const SegmenterImage& photo, const std::vector<Click>& clicks,
                             const std::vector<Click>& not_clicks, const std::optional<ViewBox>& box,
                             StageTimes* stages = nullptr);
// The same on a photo not encoded yet: encoded first ("segmenter: encode the view").
ClickedMask mask_from_prompt(const Segmenter& segmenter, const Image& photo, const std::vector<Click>& clicks,
                             const std::vector<Click>& not_clicks, const std::optional<ViewBox>& box,
                             StageTimes* stages = nullptr);

// The segmenter named by a command's --segmenter, else $INSTAINPAINT_SEGMENTER, else "auto": the
// cache's (MobileSAM before the larger SAMs; instainpaint models get mobile-sam), else none.
// "none": none; a catalogue name: its cached file.
std::optional<std::filesystem::path> segmenter_path(const std::string& flag_value);

}  // namespace ii
