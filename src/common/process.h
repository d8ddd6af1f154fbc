#pragma once
// Running outside tools (ffmpeg, colmap) without a shell: arguments are passed as they are,
// never interpreted, so paths need no quoting and cannot inject commands.
#include <filesystem>
#include <string>
#include <vector>

namespace ii {

// The absolute path of an executable: `name` itself when it contains a '/', else looked up on
// PATH. Empty when there is none.
std::filesystem::path find_executable(const std::string& name);

// Runs `exe args...` with stdin from /dev/null and stdout and stderr appended to `log`. Throws
// Error "<what> exited with status N (log: LOG); last lines:\n..." (or "was killed by signal
// N", or "<what>: could not start ...") unless it exits with status 0.
void run_logged(const std::filesystem::path& exe, const std::vector<std::string>& args,
                const std::filesystem::path& log, const std::string& what);

// The last `lines` lines of a text file ("(no log)" when it cannot be read), for messages.
std::string log_tail(const std::filesystem::path& log, int lines);

}  // namespace ii
