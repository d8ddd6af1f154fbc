#pragma once
// Starts N copies of a program on this machine as one data-parallel job, the way torchrun
// does: each gets RANK, LOCAL_RANK, WORLD_SIZE, LOCAL_WORLD_SIZE, MASTER_ADDR and
// MASTER_PORT (and OMP_NUM_THREADS = cores / N unless already set). When one copy fails,
// the others get `grace` to notice and exit on their own with their own message, then are
// terminated.
#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

namespace ii {

struct LaunchOptions {
  int processes = 2;
  std::string master_addr = "127.0.0.1";
  int master_port = 0;  // 0: a free port on this machine
  std::chrono::seconds grace{30};
};

// A TCP port that was free on 127.0.0.1 a moment ago.
int find_free_port();

// Runs `program` with `args` (argv[1..]) N times and waits for all. Returns 0 when every
// copy succeeded; otherwise logs which rank failed and how, and returns that rank's exit
// status (128 + signal when killed by a signal).
int run_local_processes(const std::filesystem::path& program, const std::vector<std::string>& args,
                        const LaunchOptions& options);

}  // namespace ii
