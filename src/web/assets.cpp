#include "web/assets.h"

#ifdef INSTAINPAINT_WEB_PAGE
extern "C" {
extern const char ii_web_index_begin[], ii_web_index_end[];
extern const char ii_web_app_begin[], ii_web_app_end[];
extern const char ii_web_app_gz_begin[], ii_web_app_gz_end[];
}
#endif

namespace ii {

const std::vector<WebAsset>& web_assets() {
  static const std::vector<WebAsset> assets = {
#ifdef INSTAINPAINT_WEB_PAGE
      {"/", "text/html; charset=utf-8",
       std::string_view(ii_web_index_begin, static_cast<size_t>(ii_web_index_end - ii_web_index_begin)),
       {}},
      {"/app.js", "text/javascript; charset=utf-8",
       std::string_view(ii_web_app_begin, static_cast<size_t>(ii_web_app_end - ii_web_app_begin)),
       std::string_view(ii_web_app_gz_begin, static_cast<size_t>(ii_web_app_gz_end - ii_web_app_gz_begin))},
#endif
  };
  return assets;
}

const WebAsset* find_web_asset(std::string_view path) {
  for (const WebAsset& a : web_assets())
    if (a.path == path || (a.path == "/" && path == "/index.html")) return &a;
  return nullptr;
}

}  // namespace ii
