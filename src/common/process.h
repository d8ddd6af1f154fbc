#pragma once
// Running outside tools (ffmpeg, colmap) without a shell: arguments are passed as they are,
// never interpreted, so paths need no quoting and cannot inject commands.
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace ii {

// The absolute path of an executable: `name` itself when it contains a '/', else looked up on
// PATH. Empty when there is none.
std::filesystem::path find_executable(const std::string& name);

// Runs `exe args...` with stdin from /dev/null and stdout and stderr appended to `log`. Throws
// Error "<what> exited with status N (log: LOG); last lines:\n..." (or "was killed by signal
// N", or "<what>: could not start ...") unless it exits with status 0. While it runs, `poll`
// (if given) is called about once a second, e.g. to report progress from the log.
void run_logged(const std::filesystem::path& exe, const std::vector<std::string>& args,
                const std::filesystem::path& log, const std::string& what,
                const std::function<void()>& poll = {});

// The last `lines` lines of a text file, read from its last 64 KB ("(no log)" when it cannot
// be read), for messages and progress.
std::string log_tail(const std::filesystem::path& log, int lines);

}  // namespace ii
