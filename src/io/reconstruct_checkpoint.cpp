#include "io/reconstruct_checkpoint.h"

#include <nlohmann/json.hpp>

#include "common/error.h"

namespace ii {

std::string checkpoint_json(const ReconstructCheckpoint& c) {
  return nlohmann::json{{"format", "instainpaint reconstruct checkpoint"},
                        {"fingerprint", c.fingerprint},
                        {"step", c.step},
                        {"fraction", c.fraction},
                        {"steps", c.steps},
                        {"time_budget_s", c.time_budget_s},
                        {"sh_degree", c.sh_degree},
                        {"seed", c.seed}}
             .dump(2) +
         "\n";
}

ReconstructCheckpoint parse_checkpoint(const std::string& text, const std::string& file) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object())
    fail("{}: not a reconstruct checkpoint (not a JSON object)", file);
  if (!j.contains("format") || !j["format"].is_string() ||
      j["format"].get<std::string>() != "instainpaint reconstruct checkpoint")
    fail("{}: not a reconstruct checkpoint (its \"format\" is not \"instainpaint reconstruct checkpoint\")", file);
  auto number = [&](const char* key, double low, double high) {
    if (!j.contains(key) || !j[key].is_number()) fail("{}: the checkpoint has no number \"{}\"", file, key);
    const double v = j[key].get<double>();
    if (!(v >= low && v <= high)) fail("{}: the checkpoint's \"{}\" {} is outside {} to {}", file, key, v, low, high);
    return v;
  };
  ReconstructCheckpoint c;
  if (!j.contains("fingerprint") || !j["fingerprint"].is_string())
    fail("{}: the checkpoint has no text \"fingerprint\"", file);
  c.fingerprint = j["fingerprint"].get<std::string>();
  c.step = static_cast<int>(number("step", 0, 1e8));
  c.fraction = number("fraction", 0, 1);
  if (c.fraction >= 1) fail("{}: the checkpoint's run had ended (fraction 1)", file);
  c.steps = static_cast<int>(number("steps", 0, 1e8));
  c.time_budget_s = number("time_budget_s", 0, 1e7);
  c.sh_degree = static_cast<int>(number("sh_degree", 0, 3));
  c.seed = static_cast<uint64_t>(number("seed", 0, 9007199254740992.0));
  if (c.steps == 0 && c.time_budget_s == 0) fail("{}: the checkpoint's run has neither steps nor a time budget", file);
  return c;
}

}  // namespace ii
