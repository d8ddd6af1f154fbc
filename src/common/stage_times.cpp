#include "common/stage_times.h"

namespace ii {

StageTimes::StageTimes(const StageTimes& other) : stages_(other.stages()) {}

StageTimes& StageTimes::operator=(const StageTimes& other) {
  if (this == &other) return *this;
  std::vector<Stage> copy = other.stages();
  std::lock_guard<std::mutex> lock(mutex_);
  stages_ = std::move(copy);
  return *this;
}

void StageTimes::add(const std::string& name, double ms, bool behind) {
  std::lock_guard<std::mutex> lock(mutex_);
  add_locked({name, ms, 1, behind});
}

void StageTimes::add_locked(const Stage& stage) {
  for (Stage& s : stages_)
    if (s.name == stage.name && s.behind == stage.behind) {
      s.ms += stage.ms;
      s.calls += stage.calls;
      return;
    }
  stages_.push_back(stage);
}

double StageTimes::lap(const std::string& name) {
  const double ms = lap_.lap();
  add(name, ms);
  return ms;
}

void StageTimes::restart_lap() { lap_.lap(); }

void StageTimes::merge(const StageTimes& other, const std::string& prefix) {
  const std::vector<Stage> theirs = other.stages();
  std::lock_guard<std::mutex> lock(mutex_);
  for (Stage s : theirs) {
    s.name = prefix + s.name;
    add_locked(s);
  }
}

double StageTimes::ms(const std::string& name) const {
  std::lock_guard<std::mutex> lock(mutex_);
  double sum = 0;
  for (const Stage& s : stages_)
    if (s.name == name) sum += s.ms;
  return sum;
}

double StageTimes::waited_ms() const {
  std::lock_guard<std::mutex> lock(mutex_);
  double sum = 0;
  for (const Stage& s : stages_)
    if (!s.behind) sum += s.ms;
  return sum;
}

std::vector<StageTimes::Stage> StageTimes::stages() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stages_;
}

nlohmann::json StageTimes::to_json() const {
  nlohmann::json out = nlohmann::json::array();
  for (const Stage& s : stages()) {
    nlohmann::json row = {{"stage", s.name}, {"ms", s.ms}, {"calls", s.calls}};
    if (s.behind) row["behind"] = true;
    out.push_back(std::move(row));
  }
  return out;
}

}  // namespace ii
