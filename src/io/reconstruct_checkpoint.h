#pragma once
// The record `instainpaint reconstruct` writes beside a checkpoint's splat file (NAME.checkpoint.json):
// which views it was trained on (a fingerprint) and how far its run got, for --resume.
#include <cstdint>
#include <string>

namespace ii {

// A checkpoint's record beside its splat file (the Gaussians as they stood): what scene, how far.
struct ReconstructCheckpoint {
  std::string fingerprint;  // scene_fingerprint of the training views
  int step = 0;             // steps done
  double fraction = 0;      // of the run, in [0, 1)
  int steps = 0;            // the run's length in steps (0: a time budget)
  double time_budget_s = 0;
  int sh_degree = 3;
  uint64_t seed = 0;
};
std::string checkpoint_json(const ReconstructCheckpoint& checkpoint);
// Error naming `file` when the text is not such a record (not JSON, a field missing or of the
// wrong type or out of range).
ReconstructCheckpoint parse_checkpoint(const std::string& text, const std::string& file);

}  // namespace ii
