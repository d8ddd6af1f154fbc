#pragma once
// The browser page `instainpaint serve` shows (web/ in the repository: bundled by esbuild at
// build time and compiled into the library, like the default model), so that the binary alone
// serves it.
#include <string_view>
#include <vector>

namespace ii {

struct WebAsset {
  std::string_view path;          // as requested, e.g. "/app.js"
  std::string_view content_type;
  std::string_view body;
  std::string_view gzip_body;     // the body gzipped at build time, or empty (small assets)
};

// Empty when the library was built without the bundle (no web/node_modules: `make deps` runs
// `npm ci` there).
const std::vector<WebAsset>& web_assets();
const WebAsset* find_web_asset(std::string_view path);

}  // namespace ii
