#pragma once
// Where a command's wall time goes: each stage's milliseconds under a name that says what it is
// ("network", "render", "write gaussians.spz"), in the order the stages first ran. eval's
// metrics.json, infer's run.json and serve's jobs report them as a list
//   [{"stage": "network", "ms": 81.9, "calls": 1}, {"stage": "render", "ms": 40.2, "calls": 40},
//    {"stage": "write gaussians.spz", "ms": 310.0, "calls": 1, "behind": true}, ...]
// that scripts/stage-table.py prints as a table. A stage run more than once (one render per
// test view) sums its calls. "behind" marks work beside the main thread (files written in the
// background, after an answer): it is not part of what the caller waited for. Thread-safe:
// background jobs add their own stages.
//
//   StageTimes stages;
//   const Scene scene = load_scene(dir);  stages.lap("read scene");
//   auto g = stages.time("network", [&] { return run(...); });
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/stopwatch.h"

namespace ii {

class StageTimes {
 public:
  struct Stage {
    std::string name;
    double ms = 0;
    int calls = 0;
    bool behind = false;
  };

  StageTimes() = default;
  StageTimes(const StageTimes& other);
  StageTimes& operator=(const StageTimes& other);

  // Adds `ms` to stage `name` (created at its first use) and counts one call.
  void add(const std::string& name, double ms, bool behind = false);
  // The time since the previous lap (or since construction or restart_lap) goes to `name`;
  // returns it.
  double lap(const std::string& name);
  // Starts the next lap now: the time since the previous one belongs to no stage.
  void restart_lap();
  // Runs fn() and adds its wall time to `name`; returns what fn returns.
  template <class Fn>
  decltype(auto) time(const std::string& name, Fn&& fn, bool behind = false) {
    Stopwatch watch;
    struct AddOnExit {
      StageTimes& times;
      const std::string& name;
      Stopwatch& watch;
      bool behind;
      ~AddOnExit() { times.add(name, watch.ms(), behind); }
    } add_on_exit{*this, name, watch, behind};
    return fn();
  }
  // Each of `other`'s stages added here (its calls too), names prefixed with `prefix`.
  void merge(const StageTimes& other, const std::string& prefix = "");

  double ms(const std::string& name) const;  // 0 for a stage that never ran
  // The stages the caller waited for (all but "behind"), summed.
  double waited_ms() const;
  std::vector<Stage> stages() const;
  nlohmann::json to_json() const;

 private:
  void add_locked(const Stage& stage);  // the caller holds mutex_

  mutable std::mutex mutex_;
  std::vector<Stage> stages_;
  Stopwatch lap_;
};

}  // namespace ii
