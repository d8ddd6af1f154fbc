#pragma once
// Work split over threads, for code that LibTorch's at::parallel_for cannot serve: in
// LibTorch 1.13 that is an OpenMP pragma in its header, which runs serially in code built
// without -fopenmp. OpenMP's threads where the compiler has OpenMP (LibTorch's own team: no
// second pool beside its waiting threads), else std::threads started per call; nested calls run
// serially (no oversubscription). The caller gives the thread count (LibTorch's: at::get_num_threads()).
// fn must make its result independent of which thread runs it.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>

namespace ii {

// How a command shares the CPU's cores: one policy for every command, CPU and GPU runs alike.
// Three kinds of threads compete: LibTorch's (the network, the rasterizer and the metrics on
// the CPU; on a GPU run only the main thread's few CPU operations), the threads decoding inputs
// ahead, and those encoding and writing outputs behind. Busy threads never outnumber the cores:
// on an H100 machine's 16 cores, LibTorch's 16 threads beside 8 decoding and 8 writing made
// eval's renders and metrics 3-4x slower (2026-11-26); LibTorch 8 and 4 + 4 gave back the speed.
struct ThreadPlan {
  int cores = 1;    // what the command may use: --threads, else $OMP_NUM_THREADS, else every core
  int compute = 1;  // LibTorch's intra-op threads: every core on a CPU run, half on a GPU run
  int files = 1;    // threads decoding ahead, and as many writing behind: a quarter of the cores each
};
// requested <= 0: $OMP_NUM_THREADS when set (a launcher's share of the machine), else every core.
ThreadPlan plan_threads(int requested, bool work_on_gpu);
// The plan of this process (set_up_runtime sets it); before that, plan_threads(0, false).
ThreadPlan thread_plan();
void set_thread_plan(const ThreadPlan& plan);

// Contiguous chunks of at least `grain` items: fn(begin, end).
void parallel_range(int64_t n, int64_t grain, int threads, const std::function<void(int64_t, int64_t)>& fn);
// fn(i) for each i, handed out one by one (for items that differ in cost).
void parallel_dynamic(int64_t n, int threads, const std::function<void(int64_t)>& fn);
// Whether the two above run on OpenMP's team (LibTorch's), not on threads of their own.
bool parallel_on_openmp();

// While alive, OpenBLAS (Debian's LibTorch's BLAS, its own pthreads) runs each call on one
// thread: LibTorch calls it from inside its OpenMP team (batched matrix products), and both
// teams on the same cores slow each other down. MobileSAM's encoder in fp32 on 2 cores: 1.197
// against 1.005 s with one BLAS thread (docs/editing.md, "With a segmentation network", its speed
// table). Nothing where the BLAS is another (PyPI's torch: MKL). Safe side by side: the count is
// restored when the last one ends.
class OneBlasThread {
 public:
  OneBlasThread();
  ~OneBlasThread();
  OneBlasThread(const OneBlasThread&) = delete;
  OneBlasThread& operator=(const OneBlasThread&) = delete;
};
// OpenBLAS's thread count now (0 where the BLAS is not OpenBLAS).
int openblas_threads();

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
