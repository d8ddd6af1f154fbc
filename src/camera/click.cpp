#include "camera/click.h"

#include <cmath>
#include <cstdlib>

#include "common/error.h"

namespace ii {

Click parse_click(const std::string& text, const std::string& option) {
  const size_t comma = text.find(',');
  char* end = nullptr;
  Click c;
  bool ok = comma != std::string::npos && comma > 0;
  if (ok) {
    const std::string x = text.substr(0, comma), y = text.substr(comma + 1);
    c.x = std::strtod(x.c_str(), &end);
    ok = end && *end == '\0';
    c.y = std::strtod(y.c_str(), &end);
    ok = ok && !y.empty() && end && *end == '\0' && std::isfinite(c.x) && std::isfinite(c.y);
  }
  if (!ok) fail("{}: '{}' is not a point: X,Y in pixels of the view's image (e.g. 512,300)", option, text);
  return c;
}

}  // namespace ii
