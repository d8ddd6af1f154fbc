#pragma once
// Videos from numbered frames, through the ffmpeg command-line tool when it is installed.
#include <filesystem>

namespace ii {

bool ffmpeg_available();

// H.264 MP4 (yuv420p; odd sizes padded to even) from FRAMES/%04d.png at `fps`. Returns false
// when ffmpeg fails; the file names are passed quoted, never interpreted by the shell.
bool encode_video(const std::filesystem::path& frames_dir, const std::filesystem::path& video, int fps);

}  // namespace ii
