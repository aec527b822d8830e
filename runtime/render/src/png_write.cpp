#include <png.h>
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <string>

#include "sandtable/render/image.h"

namespace sandtable::render {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

/// libpng reports errors by longjmp; keeping the setjmp in a function with
/// only trivially destructible locals keeps that well defined.
bool encode(std::FILE* f, const Image& img, const std::vector<png_bytep>& rows) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, info ? &info : nullptr);
    return false;
  }
  png_init_io(png, f);
  png_set_compression_level(png, 1);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
  png_set_IHDR(png, info, img.width, img.height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_rows(png, const_cast<png_bytepp>(rows.data()), img.height);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

Status writePng(const std::string& path, const Image& img) {
  const auto fail = [](std::string message) { return Problem{kPngProblem, 0, "png: " + std::move(message)}; };
  if (img.width == 0 || img.height == 0 || img.rgba.size() != std::size_t(img.width) * img.height * 4) {
    return fail(path + ": empty or inconsistent image");
  }
  std::vector<std::uint8_t> rgb(std::size_t(img.width) * img.height * 3);
  for (std::size_t p = 0, n = std::size_t(img.width) * img.height; p < n; ++p) {
    rgb[3 * p] = img.rgba[4 * p];
    rgb[3 * p + 1] = img.rgba[4 * p + 1];
    rgb[3 * p + 2] = img.rgba[4 * p + 2];
  }
  std::vector<png_bytep> rows(img.height);
  for (std::uint32_t y = 0; y < img.height; ++y) rows[y] = rgb.data() + std::size_t(y) * img.width * 3;
  // Written beside the target and renamed over it, so a reader (a video
  // encoder, a script watching the directory) never sees half a frame.
  // Not writeFileAtomic: its fsync per frame would cost more than the frame.
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(tmp.c_str(), "wb"));
  if (!f) return fail("cannot create " + tmp + " (is its directory writable?)");
  const bool encoded = encode(f.get(), img, rows);
  const bool closed = std::fclose(f.release()) == 0;
  if (!encoded || !closed) {
    std::remove(tmp.c_str());
    return fail((encoded ? "write failed for " : "libpng failed writing ") + tmp + " (is the disk full?)");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    return fail("cannot rename " + tmp + " to " + path);
  }
  return {};
}

}  // namespace sandtable::render
