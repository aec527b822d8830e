#include "icon_textures.h"

// jpeglib.h needs FILE and size_t declared first.
#include <cstdio>
#include <jpeglib.h>
#include <jerror.h>
#include <png.h>

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstring>

namespace sandtable::render::detail {
namespace {

Problem textureProblem(const std::string& name, const std::string& why) {
  return Problem{name, 0, "icon texture: " + why + "; its materials draw their base colour"};
}

/// Why an image of this size is not decoded, or "" when it may be.
std::string sizeRefusal(std::uint64_t width, std::uint64_t height) {
  if (width == 0 || height == 0 || width > kMaxImageSide || height > kMaxImageSide ||
      width * height > kMaxImageTexels) {
    return std::to_string(width) + " x " + std::to_string(height) + " texels is past the limit (" +
           std::to_string(kMaxImageSide) + " a side, " + std::to_string(kMaxImageTexels) + " in all)";
  }
  return "";
}

/// libpng's simplified API: no longjmp reaches our frames.
Result<DecodedImage> decodePng(std::span<const std::byte> bytes, const std::string& name) {
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, bytes.data(), bytes.size())) {
    return textureProblem(name, std::string("not a readable PNG (libpng: ") + image.message + ")");
  }
  if (const auto why = sizeRefusal(image.width, image.height); !why.empty()) {
    png_image_free(&image);
    return textureProblem(name, why);
  }
  image.format = PNG_FORMAT_RGBA;
  DecodedImage out{image.width, image.height, std::vector<std::uint8_t>(PNG_IMAGE_SIZE(image))};
  if (!png_image_finish_read(&image, nullptr, out.rgba.data(), 0, nullptr)) {
    const std::string why = image.message;
    png_image_free(&image);
    return textureProblem(name, "damaged PNG (libpng: " + why + ")");
  }
  return out;
}

/// libjpeg reports a fatal error through error_exit; ours jumps back to
/// the setjmp of the step that called it, whose frame holds no C++ object.
struct JpegErrors {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
  bool truncated = false;  ///< libjpeg filled missing rows with grey and only warned
};

void onJpegError(j_common_ptr cinfo) {
  auto* e = reinterpret_cast<JpegErrors*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, e->message);
  std::longjmp(e->jump, 1);
}

/// Warnings pass (GDAL lets them pass too), except a premature end of the
/// data: a cut file would otherwise draw with grey rows.
void onJpegWarning(j_common_ptr cinfo, int level) {
  auto* e = reinterpret_cast<JpegErrors*>(cinfo->err);
  if (level < 0 && cinfo->err->msg_code == JWRN_JPEG_EOF && !e->truncated) {
    e->truncated = true;
    (*cinfo->err->format_message)(cinfo, e->message);
  }
}

bool jpegStart(jpeg_decompress_struct& c, JpegErrors& e, std::span<const std::byte> bytes) {
  if (setjmp(e.jump)) return false;
  jpeg_mem_src(&c, reinterpret_cast<const unsigned char*>(bytes.data()), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&c, TRUE);
  c.out_color_space = c.num_components == 1 ? JCS_GRAYSCALE : JCS_RGB;
  return true;
}

bool jpegRows(jpeg_decompress_struct& c, JpegErrors& e, unsigned char* out, std::size_t stride) {
  if (setjmp(e.jump)) return false;
  jpeg_start_decompress(&c);
  while (c.output_scanline < c.output_height) {
    JSAMPROW row = out + std::size_t(c.output_scanline) * stride;
    jpeg_read_scanlines(&c, &row, 1);
  }
  jpeg_finish_decompress(&c);
  return true;
}

Result<DecodedImage> decodeJpeg(std::span<const std::byte> bytes, const std::string& name) {
  jpeg_decompress_struct c;
  JpegErrors e;
  c.err = jpeg_std_error(&e.mgr);
  e.mgr.error_exit = onJpegError;
  e.mgr.emit_message = onJpegWarning;
  e.message[0] = 0;
  jpeg_create_decompress(&c);
  const auto fail = [&](const std::string& why) {
    jpeg_destroy_decompress(&c);
    return textureProblem(name, why);
  };
  if (!jpegStart(c, e, bytes)) return fail(std::string("not a readable JPEG (libjpeg: ") + e.message + ")");
  if (c.num_components != 1 && c.num_components != 3) {
    return fail("a JPEG of " + std::to_string(c.num_components) + " components (CMYK?); only grey and colour draw");
  }
  if (const auto why = sizeRefusal(c.image_width, c.image_height); !why.empty()) return fail(why);
  const std::size_t channels = c.num_components == 1 ? 1 : 3;
  std::vector<unsigned char> pixels(std::size_t(c.image_width) * c.image_height * channels);
  if (!jpegRows(c, e, pixels.data(), std::size_t(c.image_width) * channels) || e.truncated) {
    return fail(std::string(e.truncated ? "truncated" : "damaged") + " JPEG (libjpeg: " + e.message + ")");
  }
  jpeg_destroy_decompress(&c);
  DecodedImage out{c.image_width, c.image_height, std::vector<std::uint8_t>(pixels.size() / channels * 4, 255)};
  for (std::size_t p = 0, n = pixels.size() / channels; p < n; ++p) {
    for (std::size_t k = 0; k < 3; ++k) out.rgba[p * 4 + k] = pixels[p * channels + (channels == 1 ? 0 : k)];
  }
  return out;
}

/// The source texels and weights of each target texel along one axis.
struct Taps {
  std::size_t first = 0;
  std::vector<double> weights;
};

std::vector<Taps> tapsFor(std::uint32_t source, std::uint32_t target) {
  const double scale = double(source) / double(target);
  const double radius = std::max(1.0, scale);
  std::vector<Taps> taps(target);
  for (std::uint32_t x = 0; x < target; ++x) {
    const double u = (x + 0.5) * scale - 0.5;  // in source texel centres
    const auto lo = std::max(0.0, std::ceil(u - radius));
    const auto hi = std::min(double(source - 1), std::floor(u + radius));
    double sum = 0;
    taps[x].first = std::size_t(lo);
    for (double i = lo; i <= hi; ++i) {
      const double w = std::max(0.0, 1.0 - std::abs(i - u) / radius);
      taps[x].weights.push_back(w);
      sum += w;
    }
    for (double& w : taps[x].weights) w /= sum;
  }
  return taps;
}

}  // namespace

Result<DecodedImage> decodeImage(std::span<const std::byte> bytes, const std::string& name) {
  const auto* b = reinterpret_cast<const unsigned char*>(bytes.data());
  if (bytes.empty()) return textureProblem(name, "empty");
  if (bytes.size() >= 8 && png_sig_cmp(b, 0, 8) == 0) return decodePng(bytes, name);
  if (bytes.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) return decodeJpeg(bytes, name);
  return textureProblem(name, "neither PNG nor JPEG, the image formats icon textures draw from");
}

std::vector<std::uint8_t> resampleSquare(const DecodedImage& img, std::uint32_t texels) {
  const auto across = tapsFor(img.width, texels), down = tapsFor(img.height, texels);
  // Rows first (each source row to `texels` columns), then columns.
  std::vector<double> rows(std::size_t(img.height) * texels * 4);
  for (std::size_t y = 0; y < img.height; ++y) {
    for (std::size_t x = 0; x < texels; ++x) {
      for (std::size_t k = 0; k < 4; ++k) {
        double v = 0;
        for (std::size_t t = 0; t < across[x].weights.size(); ++t) {
          v += across[x].weights[t] * img.rgba[(y * img.width + across[x].first + t) * 4 + k];
        }
        rows[(y * texels + x) * 4 + k] = v;
      }
    }
  }
  std::vector<std::uint8_t> out(std::size_t(texels) * texels * 4);
  for (std::size_t y = 0; y < texels; ++y) {
    const std::size_t glRow = texels - 1 - y;  // the image's top row is GL's t = 1
    for (std::size_t x = 0; x < texels; ++x) {
      for (std::size_t k = 0; k < 4; ++k) {
        double v = 0;
        for (std::size_t t = 0; t < down[y].weights.size(); ++t) {
          v += down[y].weights[t] * rows[((down[y].first + t) * texels + x) * 4 + k];
        }
        out[(glRow * texels + x) * 4 + k] = std::uint8_t(std::clamp(std::floor(v + 0.5), 0.0, 255.0));
      }
    }
  }
  return out;
}

Result<std::vector<std::uint8_t>> decodeIconTexture(std::span<const std::byte> bytes, const std::string& name,
                                                    std::uint32_t texels) {
  auto img = decodeImage(bytes, name);
  if (!img) return img.problems();
  return resampleSquare(img.value(), texels);
}

GLuint createTextureArray(std::uint32_t texels, std::uint32_t layers, GLenum wrap) {
  const auto mips = GLsizei(std::log2(double(texels))) + 1;
  GLuint tex = 0;
  glCreateTextures(GL_TEXTURE_2D_ARRAY, 1, &tex);
  glTextureStorage3D(tex, mips, GL_RGBA8, GLsizei(texels), GLsizei(texels), GLsizei(layers));
  glTextureParameteri(tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTextureParameteri(tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTextureParameteri(tex, GL_TEXTURE_WRAP_S, GLint(wrap));
  glTextureParameteri(tex, GL_TEXTURE_WRAP_T, GLint(wrap));
  return tex;
}

GLuint uploadIconTextures(const iconpack::Pack& pack, std::vector<std::string>& warnings) {
  if (pack.textures.empty()) return 0;
  const auto n = GLsizei(kIconTextureTexels);
  const GLuint tex = createTextureArray(kIconTextureTexels, std::uint32_t(pack.textures.size()), GL_REPEAT);
  for (std::size_t k = 0; k < pack.textures.size(); ++k) {
    auto rgba = decodeIconTexture(pack.textures[k].bytes, pack.textures[k].name);
    std::vector<std::uint8_t> white;
    if (!rgba) {
      warnings.push_back(rgba.error());
      white.assign(std::size_t(n) * std::size_t(n) * 4, 255);
    }
    glTextureSubImage3D(tex, 0, 0, 0, GLint(k), n, n, 1, GL_RGBA, GL_UNSIGNED_BYTE,
                        rgba ? rgba.value().data() : white.data());
  }
  glGenerateTextureMipmap(tex);
  return tex;
}

}  // namespace sandtable::render::detail
