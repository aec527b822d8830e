#pragma once
// An RGBA8 frame in memory, top row first, and its PNG writer.
//
// Thread safety: plain data; writePng touches only its arguments.
#include <cstdint>
#include <string>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::render {

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
};

struct Image {
  std::uint32_t width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  ///< width * height * 4 bytes, top row first

  Rgb at(std::uint32_t x, std::uint32_t y) const {
    const std::size_t k = (std::size_t(y) * width + x) * 4;
    return {rgba[k], rgba[k + 1], rgba[k + 2]};
  }
};

/// Problem::file of PNG writing problems (the message names the path).
inline constexpr const char* kPngProblem = "png";

/// Writes `img` as an 8-bit RGB PNG (alpha dropped: frames are opaque).
/// Fast zlib level: frames are many and large.
Status writePng(const std::string& path, const Image& img);

}  // namespace sandtable::render
