#include "common/parallel.h"

#include <dlfcn.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#ifdef II_PARALLEL_OPENMP
#include <omp.h>
#endif

namespace ii {

namespace {

thread_local bool t_in_worker = false;

// Runs fn(t, team) for t in [0, team) at once, t = 0 on the calling thread, team <= threads;
// rethrows the first exception after all have finished.
//
// Built with OpenMP, the team is OpenMP's, the one LibTorch's operations use: its threads wait
// by spinning for a while after each parallel region, so a second pool of threads started right
// after a LibTorch operation shares the cores with them (on 2 cores `fill` of 1 M splats took
// 3.36 s so, 2.89 s on OpenMP's team). Without OpenMP (the sanitizer build's clang), plain std::threads.
void run_team(int threads, const std::function<void(int, int)>& fn) {
  if (threads <= 1) {
    fn(0, 1);
    return;
  }
  std::exception_ptr error;
  std::mutex mutex;
  auto guarded = [&](int t, int team) {
    const bool outer = t_in_worker;
    t_in_worker = true;
    try {
      fn(t, team);
    } catch (...) {
      const std::lock_guard<std::mutex> lock(mutex);
      if (!error) error = std::current_exception();
    }
    t_in_worker = outer;
  };
#ifdef II_PARALLEL_OPENMP
#pragma omp parallel num_threads(threads)
  guarded(omp_get_thread_num(), omp_get_num_threads());
#else
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(guarded, t, threads);
  guarded(0, threads);
  for (std::thread& th : pool) th.join();
#endif
  if (error) std::rethrow_exception(error);
}

// 1 inside a worker, and never more threads than tasks.
int thread_budget(int threads, int64_t tasks) {
  if (t_in_worker || tasks <= 1) return 1;
  return static_cast<int>(std::max<int64_t>(1, std::min<int64_t>(threads, tasks)));
}

}  // namespace

void parallel_range(int64_t n, int64_t grain, int threads, const std::function<void(int64_t, int64_t)>& fn) {
  if (n <= 0) return;
  run_team(thread_budget(threads, (n + grain - 1) / std::max<int64_t>(grain, 1)), [&](int t, int team) {
    const int64_t chunk = (n + team - 1) / team, b = t * chunk, e = std::min(n, b + chunk);
    if (b < e) fn(b, e);
  });
}

void parallel_dynamic(int64_t n, int threads, const std::function<void(int64_t)>& fn) {
  if (n <= 0) return;
  std::atomic<int64_t> next{0};
  run_team(thread_budget(threads, n), [&](int, int) {
    for (int64_t i = next++; i < n; i = next++) fn(i);
  });
}

bool parallel_on_openmp() {
#ifdef II_PARALLEL_OPENMP
  return true;
#else
  return false;
#endif
}

ThreadPlan plan_threads(int requested, bool work_on_gpu) {
  int cores = requested;
  if (cores <= 0)
    if (const char* omp = std::getenv("OMP_NUM_THREADS")) cores = std::atoi(omp);
  if (cores <= 0) cores = static_cast<int>(std::thread::hardware_concurrency());
  ThreadPlan plan;
  plan.cores = std::max(1, cores);
  plan.compute = work_on_gpu ? std::max(1, plan.cores / 2) : plan.cores;
  plan.files = std::max(1, plan.cores / 4);
  return plan;
}

namespace {
std::mutex plan_mutex;
std::optional<ThreadPlan> process_plan;
}  // namespace

ThreadPlan thread_plan() {
  std::lock_guard<std::mutex> lock(plan_mutex);
  if (!process_plan) process_plan = plan_threads(0, false);
  return *process_plan;
}

void set_thread_plan(const ThreadPlan& plan) {
  std::lock_guard<std::mutex> lock(plan_mutex);
  process_plan = plan;
}

namespace {
using SetThreads = void (*)(int);
using GetThreads = int (*)();
// OpenBLAS's own functions, looked up in the process (no link to OpenBLAS itself).
SetThreads openblas_set() { return reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads")); }
GetThreads openblas_get() { return reinterpret_cast<GetThreads>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads")); }
std::mutex blas_mutex;
int blas_holders = 0, blas_before = 0;
}  // namespace

int openblas_threads() {
  const GetThreads get = openblas_get();
  return get ? get() : 0;
}

OneBlasThread::OneBlasThread() {
  const SetThreads set = openblas_set();
  const GetThreads get = openblas_get();
  if (!set || !get) return;
  std::lock_guard<std::mutex> lock(blas_mutex);
  if (blas_holders++ == 0) {
    blas_before = get();
    set(1);
  }
}

OneBlasThread::~OneBlasThread() {
  const SetThreads set = openblas_set();
  if (!set || !openblas_get()) return;
  std::lock_guard<std::mutex> lock(blas_mutex);
  if (--blas_holders == 0) set(blas_before);
}

BackgroundJobs::~BackgroundJobs() {
  for (auto& f : pending_)
    if (f.valid()) f.wait();
}

void BackgroundJobs::add(std::function<void()> job) {
  while (pending_.size() >= limit_) {
    pending_.front().get();
    pending_.pop_front();
  }
  pending_.push_back(std::async(std::launch::async, std::move(job)));
}

void BackgroundJobs::finish() {
  while (!pending_.empty()) {
    pending_.front().get();
    pending_.pop_front();
  }
}

}  // namespace ii
