#pragma once
// The geometry's settings as one table. Each row is one setting of GeometryOptions as the user
// gives it: the commands' flag (`--frame-margin`), Python's keyword of Predictor.predict
// (`frame_margin`), its help, its range or choices, and for a step's switch the value that turns
// the step off (GeometryOptions::papers()) and whether an insertion turns it off
// (GeometryOptions::for_insertion()). A new setting is one row here.
#include <functional>
#include <string>
#include <vector>

#include "geometry/options.h"

namespace ii {

struct GeometrySetting {
  std::string name;  // the flag without its "--"; Python's keyword is the same with '_' for '-'
  std::string help;
  std::string kind;                  // "number", "integer", "bool" or "choice"
  double min = 0, max = 0;           // a number's or an integer's range
  std::vector<std::string> choices;  // a choice's names
  std::string off;                   // the value that turns its step off (the paper's); empty: not a switch
  bool off_for_insertion = false;    // an insertion's region holds a new object, not what lay behind
  // The value in `options`, as text ("0.125", "true", "photos").
  std::function<std::string(const GeometryOptions& options)> get;
  // Sets it from text checked against the row (check_geometry_setting).
  std::function<void(GeometryOptions& options, const std::string& text)> put;
};

// Every setting, in the order the commands' help lists them.
const std::vector<GeometrySetting>& geometry_settings();

// The row named `name` (a flag without "--", or Python's keyword): an Error listing the names otherwise.
const GeometrySetting& geometry_setting(const std::string& name);

// Whether `text` is a value of `setting`: "" when it is, else what it takes ("a number from 0 to
// 1", "none, depth-maps, photos or any").
std::string check_geometry_setting(const GeometrySetting& setting, const std::string& text);

// Sets the setting `name` of `options` from `text`: an Error naming the flag, the text and what it
// takes otherwise ("--frame-margin '2': a number from 0 to 1").
void set_geometry_setting(GeometryOptions& options, const std::string& name, const std::string& text);

}  // namespace ii
