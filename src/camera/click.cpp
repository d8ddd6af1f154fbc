#include "camera/click.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

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

ViewBox parse_view_box(const std::string& text, const std::string& what) {
  ViewBox b{};
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream in(text);
  if (!(in >> b[0] >> c1 >> b[1] >> c2 >> b[2] >> c3 >> b[3]) || c1 != ',' || c2 != ',' || c3 != ',' || !in.eof() ||
      !std::isfinite(b[0] + b[1] + b[2] + b[3]) || b[2] <= b[0] || b[3] <= b[1])
    fail("{} {}: expected X0,Y0,X1,Y1 with X1 > X0 and Y1 > Y0", what, text);
  return b;
}

}  // namespace ii
