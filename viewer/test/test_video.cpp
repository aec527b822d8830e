// Video through ffmpeg when it is installed; skipped when it is not (it is
// optional). The not-installed message is checked either way.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "sandtable/viewer/video.h"
#include "sandtable/testing/require.h"

namespace sandtable::viewer {
namespace {

namespace fs = std::filesystem;

render::Image frame(std::uint32_t w, std::uint32_t h, std::uint8_t shade) {
  render::Image img;
  img.width = w;
  img.height = h;
  img.rgba.assign(std::size_t(w) * h * 4, shade);
  return img;
}

fs::path tempVideo(const std::string& name) {
  return fs::temp_directory_path() / ("sandtable-video-" + std::to_string(::getpid()) + "-" + name);
}

TEST(Video, MissingFfmpegSaysHowToInstallIt) {
  VideoOptions o;
  o.ffmpeg = "sandtable-no-such-ffmpeg";
  EXPECT_FALSE(VideoWriter::available(o.ffmpeg));
  auto v = VideoWriter::open(tempVideo("none.mp4").string(), 64, 48, o);
  ASSERT_FALSE(v.ok());
  EXPECT_NE(v.error().find("apt-get install ffmpeg"), std::string::npos) << v.error();
}

TEST(Video, WritesAnMp4) {
  SANDTABLE_REQUIRE(VideoWriter::available(), "ffmpeg: " << VideoWriter::notInstalledMessage());
  const fs::path out = tempVideo("odd.mp4");
  auto v = VideoWriter::open(out.string(), 65, 47);  // odd: padded for yuv420p
  ASSERT_TRUE(v.ok()) << v.error();
  for (int k = 0; k < 10; ++k) ASSERT_TRUE(v.value()->write(frame(65, 47, std::uint8_t(k * 20))).ok());
  const Status wrongSize = v.value()->write(frame(64, 48, 0));
  ASSERT_FALSE(wrongSize.ok());
  EXPECT_EQ(wrongSize.problems().front().file, kVideoProblem);
  EXPECT_NE(wrongSize.error().find("the video is 65x47"), std::string::npos);
  EXPECT_EQ(v.value()->framesWritten(), 10u);
  EXPECT_TRUE(v.value()->finish().ok());
  ASSERT_TRUE(fs::exists(out));
  EXPECT_GT(fs::file_size(out), 0u);
  EXPECT_FALSE(fs::exists(out.string() + ".ffmpeg.log"));
  fs::remove(out);
}

TEST(Video, MissingDirectoryIsReportedAtOpen) {
  SANDTABLE_REQUIRE(VideoWriter::available(), "ffmpeg: " << VideoWriter::notInstalledMessage());
  const fs::path out = tempVideo("no-such-dir") / "x.mp4";
  auto v = VideoWriter::open(out.string(), 32, 32);
  ASSERT_FALSE(v.ok());
  EXPECT_NE(v.error().find("is the video's directory there and writable?"), std::string::npos) << v.error();
}

TEST(Video, FfmpegFailureIsReported) {
  SANDTABLE_REQUIRE(VideoWriter::available(), "ffmpeg: " << VideoWriter::notInstalledMessage());
  const fs::path out = tempVideo("bad-preset.mp4");
  VideoOptions o;
  o.preset = "no-such-preset";  // x264 refuses it: ffmpeg exits with an error
  auto v = VideoWriter::open(out.string(), 32, 32, o);
  ASSERT_TRUE(v.ok()) << v.error();
  std::string err;
  for (int k = 0; k < 200 && err.empty(); ++k) err = v.value()->write(frame(32, 32, 0)).error();
  if (err.empty()) err = v.value()->finish().error();
  EXPECT_NE(err.find("ffmpeg"), std::string::npos) << err;
  EXPECT_NE(err.find("exit status"), std::string::npos) << err;
  fs::remove(out);
  fs::remove(out.string() + ".ffmpeg.log");
}

}  // namespace
}  // namespace sandtable::viewer
