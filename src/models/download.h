#pragma once
// Fetching a catalogue entry into the cache over HTTP(S) with libcurl: proxies from the usual
// variables, redirects followed, a time-out on connecting and on a stalled transfer, resumed
// where a cut transfer stopped (the partial file kept as "<file>.part"), checked before it is
// moved into place, one download of a file at a time (others wait on "<file>.lock").
#include <functional>
#include <optional>
#include <string>

#include "models/cache.h"

namespace ii {

struct DownloadOptions {
  // A base URL holding the same file names (else $INSTAINPAINT_MODELS_MIRROR, else the
  // entry's own locations).
  std::string mirror;
  // Seconds to connect, and seconds without a byte before a transfer is abandoned.
  double timeout_s = 30;
  // Progress: a bar on a terminal, else a line per file. Off: nothing printed.
  bool progress = true;
};

// The entry's file in the cache, downloaded (or resumed) and checked when it is not there yet.
// Throws an Error naming the entry, the URL and the problem; a file that fails its checksum is
// deleted and the message gives both checksums.
CachedModel download_model(const ModelEntry& entry, const DownloadOptions& options = {});

// "instainpaint models get NAME": what a command prints where a network is missing.
std::string get_command(const std::string& name);

}  // namespace ii
