#pragma once
// One thread for all of a long-lived program's LibTorch work (the server's). libgomp, the OpenMP
// of both LibTorch builds, lets its idle workers spin only while the process holds no more
// OpenMP threads than cores; every other thread that starts LibTorch work keeps a team of its own,
// and from then on each parallel region wakes its workers from sleep. On 2 cores a click's
// decoder took 110-135 ms on a request's thread against 62-72 ms on a process's only such thread
// (docs/benchmarks.md, "The page with the learned networks").
#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <mutex>
#include <thread>
#include <type_traits>

namespace ii {

class ComputeThread {
 public:
  ComputeThread();
  ~ComputeThread();  // finishes what was posted, then ends the thread
  ComputeThread(const ComputeThread&) = delete;
  ComputeThread& operator=(const ComputeThread&) = delete;

  // fn() on the compute thread, waited for (its exception rethrown here); on the compute
  // thread itself, at once.
  template <typename Fn>
  std::invoke_result_t<Fn&> run(Fn&& fn) {
    if (on_this_thread()) return fn();
    std::packaged_task<std::invoke_result_t<Fn&>()> task(std::forward<Fn>(fn));
    auto result = task.get_future();
    // Idle again before the caller has the result: busy() right after run() returns says false.
    std::promise<void> finished;
    auto done = finished.get_future();
    post([this, &task, &finished] {  // both live until done.wait() returns
      task();
      mark_idle();
      finished.set_value();
    });
    done.wait();
    return result.get();
  }
  // As run() while the compute thread is idle; while it works (a job of minutes), fn() on the
  // caller's thread instead of waiting behind it.
  template <typename Fn>
  std::invoke_result_t<Fn&> run_if_idle(Fn&& fn) {
    if (busy() && !on_this_thread()) return fn();
    return run(std::forward<Fn>(fn));
  }
  bool on_this_thread() const { return std::this_thread::get_id() == thread_.get_id(); }
  bool busy() const;

 private:
  void post(std::function<void()> job);
  void mark_idle();
  void loop();
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::function<void()>> queue_;
  bool working_ = false, stopping_ = false;
  std::thread thread_;
};

}  // namespace ii
