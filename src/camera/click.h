#pragma once
// A click on a view: where a user points at an object (edit/select.h selects what is there).
#include <array>
#include <string>

namespace ii {

// A click in pixels of a view's image as stored (x right, y down; a pixel's centre at +0.5).
struct Click {
  double x = 0, y = 0;
};
// "X,Y": an Error naming `option` otherwise.
Click parse_click(const std::string& text, const std::string& option);

// A box drawn around an object on a view: x0, y0, x1, y1 in pixels of its image as stored, edges
// as drawn (a box of a whole 504 x 378 photo is 0, 0, 504, 378).
using ViewBox = std::array<double, 4>;
// "X0,Y0,X1,Y1" as a box (an Error naming `what` unless four numbers with X1 > X0 and Y1 > Y0).
ViewBox parse_view_box(const std::string& text, const std::string& what);

}  // namespace ii
