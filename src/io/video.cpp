#include "io/video.h"

#include <fmt/format.h>

#include <cstdlib>
#include <string>

#include "common/process.h"

namespace ii {

namespace {
std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}
}  // namespace

bool ffmpeg_available() { return !find_executable("ffmpeg").empty(); }

bool encode_video(const std::filesystem::path& frames_dir, const std::filesystem::path& video, int fps) {
  const std::string cmd = fmt::format(
      "ffmpeg -y -loglevel error -framerate {} -i {} -c:v libx264 -pix_fmt yuv420p "
      "-vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' {}",
      fps, shell_quote((frames_dir / "%04d.png").string()), shell_quote(video.string()));
  return std::system(cmd.c_str()) == 0;
}

}  // namespace ii
