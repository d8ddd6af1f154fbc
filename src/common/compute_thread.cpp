#include "common/compute_thread.h"

namespace ii {

ComputeThread::ComputeThread() : thread_([this] { loop(); }) {}

ComputeThread::~ComputeThread() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

bool ComputeThread::busy() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return working_ || !queue_.empty();
}

void ComputeThread::post(std::function<void()> job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back(std::move(job));
  }
  changed_.notify_all();
}

void ComputeThread::mark_idle() {
  std::lock_guard<std::mutex> lock(mutex_);
  working_ = false;
}

void ComputeThread::loop() {
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, and everything posted is done
      job = std::move(queue_.front());
      queue_.pop_front();
      working_ = true;
    }
    job();  // a packaged_task: its exception goes to its future
    std::lock_guard<std::mutex> lock(mutex_);
    working_ = false;
  }
}

}  // namespace ii
