#pragma once
// Work split over threads, for code that LibTorch's at::parallel_for cannot serve: in
// LibTorch 1.13 that is an OpenMP pragma in its header, which runs serially in code built
// without -fopenmp. Plain std::threads, started per call; nested calls run serially (no
// oversubscription). The caller gives the thread count (LibTorch's: at::get_num_threads()).
// fn must make its result independent of which thread runs it.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>

namespace ii {

// Contiguous chunks of at least `grain` items: fn(begin, end).
void parallel_range(int64_t n, int64_t grain, int threads, const std::function<void(int64_t, int64_t)>& fn);
// fn(i) for each i, handed out one by one (for items that differ in cost).
void parallel_dynamic(int64_t n, int threads, const std::function<void(int64_t)>& fn);

// Jobs (file writes: PNG encoding, the atomic writes' fsync) on background threads while the
// caller goes on, at most `limit` at a time: add() waits for the oldest when that many run.
// add() and finish() rethrow the first failure; the destructor waits for what still runs.
class BackgroundJobs {
 public:
  explicit BackgroundJobs(size_t limit) : limit_(limit < 1 ? 1 : limit) {}
  BackgroundJobs(const BackgroundJobs&) = delete;
  BackgroundJobs& operator=(const BackgroundJobs&) = delete;
  ~BackgroundJobs();
  void add(std::function<void()> job);
  void finish();

 private:
  size_t limit_;
  std::deque<std::future<void>> pending_;
};

}  // namespace ii
