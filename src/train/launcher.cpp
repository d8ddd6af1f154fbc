#include "train/launcher.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <map>
#include <thread>

#include "common/error.h"

extern char** environ;

namespace ii {

int find_free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) fail("cannot open a socket to find a free port: {}", std::strerror(errno));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof(addr);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    fail("cannot find a free TCP port: {}", why);
  }
  ::close(fd);
  return ntohs(addr.sin_port);
}

namespace {

std::string describe(int status) {
  if (WIFEXITED(status)) return fmt::format("exited with code {}", WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return fmt::format("was killed by signal {} ({})", WTERMSIG(status), strsignal(WTERMSIG(status)));
  return "stopped";
}

int exit_code(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 1;
}

// The environment of rank `rank`: ours with the torchrun variables replaced.
std::vector<std::string> child_environment(int rank, int world, const std::string& addr, int port) {
  const std::map<std::string, std::string> set = {
      {"RANK", std::to_string(rank)},         {"LOCAL_RANK", std::to_string(rank)},
      {"WORLD_SIZE", std::to_string(world)},  {"LOCAL_WORLD_SIZE", std::to_string(world)},
      {"MASTER_ADDR", addr},                  {"MASTER_PORT", std::to_string(port)}};
  std::vector<std::string> env;
  bool has_omp = false;
  for (char** e = environ; *e; ++e) {
    const std::string entry = *e;
    const std::string key = entry.substr(0, entry.find('='));
    if (set.count(key)) continue;
    has_omp = has_omp || key == "OMP_NUM_THREADS";
    env.push_back(entry);
  }
  for (const auto& [k, v] : set) env.push_back(k + "=" + v);
  // N processes with all cores each would oversubscribe the machine.
  if (!has_omp) {
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    env.push_back("OMP_NUM_THREADS=" + std::to_string(std::max(1u, cores / static_cast<unsigned>(world))));
  }
  return env;
}

}  // namespace

int run_local_processes(const std::filesystem::path& program, const std::vector<std::string>& args,
                        const LaunchOptions& options) {
  if (options.processes < 1) fail("--nproc must be at least 1, got {}", options.processes);
  const int port = options.master_port > 0 ? options.master_port : find_free_port();
  std::map<pid_t, int> running;  // pid -> rank
  for (int rank = 0; rank < options.processes; ++rank) {
    // Build everything before fork: the child only calls execve.
    std::vector<std::string> env = child_environment(rank, options.processes, options.master_addr, port);
    std::vector<std::string> argv_strings{program.string()};
    argv_strings.insert(argv_strings.end(), args.begin(), args.end());
    std::vector<char*> argv, envp;
    for (std::string& s : argv_strings) argv.push_back(s.data());
    argv.push_back(nullptr);
    for (std::string& s : env) envp.push_back(s.data());
    envp.push_back(nullptr);
    const pid_t pid = ::fork();
    if (pid < 0) fail("cannot start process {} of {}: {}", rank, options.processes, std::strerror(errno));
    if (pid == 0) {
      ::execve(argv[0], argv.data(), envp.data());
      std::fprintf(stderr, "error: cannot run %s: %s\n", argv[0], std::strerror(errno));
      ::_exit(127);
    }
    running[pid] = rank;
  }
  spdlog::info("started {} processes (rendezvous {}:{})", options.processes, options.master_addr, port);

  int result = 0;
  std::chrono::steady_clock::time_point deadline{};
  bool terminated = false;
  while (!running.empty()) {
    int status = 0;
    const pid_t pid = ::waitpid(-1, &status, result != 0 ? WNOHANG : 0);
    if (pid < 0) {
      if (errno == EINTR) continue;
      break;
    }
    if (pid == 0) {  // a failure happened, others still running
      const auto now = std::chrono::steady_clock::now();
      if (!terminated && now >= deadline) {
        spdlog::error("stopping the {} remaining process(es)", running.size());
        for (const auto& [p, r] : running) ::kill(p, SIGTERM);
        terminated = true;
        deadline = now + std::chrono::seconds(5);
      } else if (terminated && now >= deadline) {
        for (const auto& [p, r] : running) ::kill(p, SIGKILL);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      continue;
    }
    auto it = running.find(pid);
    if (it == running.end()) continue;
    const int rank = it->second;
    running.erase(it);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) continue;
    if (result == 0) {
      spdlog::error("rank {} {}", rank, describe(status));
      result = exit_code(status);
      deadline = std::chrono::steady_clock::now() + options.grace;
    } else {
      spdlog::debug("rank {} {}", rank, describe(status));
    }
  }
  return result;
}

}  // namespace ii
