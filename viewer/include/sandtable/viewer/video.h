#pragma once
// A video of a flight through the ffmpeg program, when it is installed
// (it is optional: tools/setup.sh does not require it). Frames go to
// ffmpeg's stdin as raw RGBA; ffmpeg encodes H.264 (yuv420p, so any
// player shows it) into an .mp4, .mkv or whatever the path's extension
// says. Odd sizes are padded by one pixel, as yuv420p needs even ones.
//
// Thread safety: one VideoWriter per thread. write() blocks SIGPIPE on the
// calling thread only while it writes, so an ffmpeg that died reports an
// error instead of killing the process.
#include <cstdint>
#include <memory>
#include <string>

#include "sandtable/base/result.h"
#include "sandtable/render/image.h"

namespace sandtable::viewer {

/// Problem::file of video problems.
inline constexpr const char* kVideoProblem = "video";

struct VideoOptions {
  double fps = 30;
  int crf = 20;                       ///< x264 quality: lower is better and bigger
  std::string preset = "veryfast";    ///< x264 speed / size trade-off
  std::string ffmpeg = "ffmpeg";      ///< program name or path, looked up on PATH
};

class VideoWriter {
 public:
  /// True when `program` is an executable on PATH (or a path to one).
  static bool available(const std::string& program = "ffmpeg");
  /// What to tell the user when it is not.
  static std::string notInstalledMessage();

  /// Starts ffmpeg writing `path` (overwritten). Fails if ffmpeg is not
  /// installed or cannot be started.
  static Result<std::unique_ptr<VideoWriter>> open(const std::string& path, std::uint32_t width,
                                                   std::uint32_t height, const VideoOptions& options = {});
  ~VideoWriter();  ///< finishes the file if finish() was not called
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;

  /// Sends one frame; it must have the size given to open().
  Status write(const render::Image& frame);
  /// Closes the pipe and waits for ffmpeg. Fails with ffmpeg's exit
  /// status and the end of what it printed.
  Status finish();

  std::uint64_t framesWritten() const { return frames_; }
  const std::string& path() const { return path_; }

 private:
  VideoWriter() = default;
  std::string path_, logPath_;
  std::uint32_t width_ = 0, height_ = 0;
  int fd_ = -1;
  int pid_ = -1;
  std::uint64_t frames_ = 0;
  bool finished_ = false;
};

}  // namespace sandtable::viewer
