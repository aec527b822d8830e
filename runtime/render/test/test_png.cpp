// writePng: a frame lands whole under its name, never half written, and a
// failure leaves nothing behind.
#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>

#include "sandtable/render/image.h"

namespace sandtable::render {
namespace {

namespace fs = std::filesystem;

Image gradient(std::uint32_t w, std::uint32_t h) {
  Image img{w, h, std::vector<std::uint8_t>(std::size_t(w) * h * 4, 255)};
  for (std::uint32_t y = 0; y < h; ++y) {
    for (std::uint32_t x = 0; x < w; ++x) img.rgba[(std::size_t(y) * w + x) * 4] = std::uint8_t(x * 255 / (w - 1));
  }
  return img;
}

TEST(Png, writesTheFrameUnderItsNameAndNoTemporary) {
  const fs::path dir = fs::temp_directory_path() / ("sandtable-png." + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string file = (dir / "frame.png").string();
  ASSERT_TRUE(writePng(file, gradient(64, 8)).ok());
  ASSERT_TRUE(writePng(file, gradient(32, 4)).ok());  // replaces the first
  std::size_t entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) entries += e.path().filename() == "frame.png" ? 1 : 100;
  EXPECT_EQ(entries, 1u) << "only the frame, no temporary file";
  // libpng reads back what was written last (independent decoder).
  png_image back{};
  back.version = PNG_IMAGE_VERSION;
  ASSERT_TRUE(png_image_begin_read_from_file(&back, file.c_str())) << back.message;
  EXPECT_EQ(back.width, 32u);
  EXPECT_EQ(back.height, 4u);
  png_image_free(&back);
  // A directory that does not exist: a png problem naming the file, nothing created.
  const std::string missing = (dir / "no" / "frame.png").string();
  const Status st = writePng(missing, gradient(8, 8));
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("frame.png"), std::string::npos) << st.error();
  EXPECT_FALSE(fs::exists(dir / "no"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sandtable::render
