#pragma once
// A click on a view: where a user points at an object (edit/select.h selects what is there).
#include <string>

namespace ii {

// A click in pixels of a view's image as stored (x right, y down; a pixel's centre at +0.5).
struct Click {
  double x = 0, y = 0;
};
// "X,Y": an Error naming `option` otherwise.
Click parse_click(const std::string& text, const std::string& option);

}  // namespace ii
