// Fuzz target of the models' catalogue file ($INSTAINPAINT_MODELS_CATALOGUE, models/catalogue.h).
#include "common/error.h"
#include "fuzz_target.h"
#include "models/catalogue.h"

namespace ii::fuzz {
namespace {

const bool model_catalogue = register_target({
    "model_catalogue",
    [] {
      return std::vector<std::string>{
          R"([{"name":"mobile-sam","role":"segmenter","file":"mobile_sam.pt","urls":["http://127.0.0.1:8000/mobile_sam.pt"],)"
          R"("md5":"f3c0d8cda613564d499310dab6c812cd","checksum_source":"IOPaint","size":40728226,"licence":"Apache-2.0"}])",
          R"([{"name":"instainpaint","role":"checkpoint","file":"exp_ins+random+3d_121_multimask.pth",)"
          R"("urls":["https://example.org/a.pth","https://example.org/b.pth"]}])"};
    },
    [](const uint8_t* data, size_t size) {
      parse_model_catalogue(std::string(reinterpret_cast<const char*>(data), size), "catalogue.json");
    }});

}  // namespace
}  // namespace ii::fuzz
