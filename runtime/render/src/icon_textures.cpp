#include "icon_textures.h"

#include <gdal_priv.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>

namespace sandtable::runtime::detail {
namespace {

/// A /vsimem/ file over caller-owned bytes, unlinked on destruction.
class MemFile {
 public:
  explicit MemFile(std::span<const std::byte> bytes) {
    static std::atomic<std::uint64_t> next{0};
    path_ = "/vsimem/sandtable-icon-texture-" + std::to_string(next++);
    // GDAL does not write through the pointer of a file it does not own.
    auto* data = reinterpret_cast<GByte*>(const_cast<std::byte*>(bytes.data()));
    VSIFCloseL(VSIFileFromMemBuffer(path_.c_str(), data, vsi_l_offset(bytes.size()), FALSE));
  }
  ~MemFile() { VSIUnlink(path_.c_str()); }
  MemFile(const MemFile&) = delete;
  MemFile& operator=(const MemFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace

Result<std::vector<std::uint8_t>> decodeIconTexture(std::span<const std::byte> bytes, const std::string& name,
                                                    std::uint32_t texels) {
  GDALAllRegister();
  const auto fail = [&](const std::string& why) {
    return Problem{name, 0, "icon texture: " + why + "; its materials draw their base colour"};
  };
  if (bytes.empty()) return fail("empty");
  MemFile file(bytes);
  const char* const drivers[] = {"PNG", "JPEG", "GTiff", "BMP", "GIF", "WEBP", nullptr};
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(file.path().c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, drivers, nullptr, nullptr));
  if (!ds || ds->GetRasterCount() < 1) return fail("GDAL cannot read it as an image");
  const int bands = ds->GetRasterCount();
  std::vector<std::uint8_t> rgba(std::size_t(texels) * texels * 4, 255);
  GDALRasterIOExtraArg extra;
  INIT_RASTERIO_EXTRA_ARG(extra);
  extra.eResampleAlg = GRIORA_Bilinear;
  // Channel c comes from band c + 1, grey spread to all three, alpha from
  // band 4 (or 2 for grey with alpha) where there is one.
  for (int c = 0; c < 4; ++c) {
    int band = 0;
    if (c < 3) band = bands >= 3 ? c + 1 : 1;
    if (c == 3) band = bands >= 4 ? 4 : bands == 2 ? 2 : 0;
    if (band == 0) continue;
    const CPLErr e = ds->GetRasterBand(band)->RasterIO(
        GF_Read, 0, 0, ds->GetRasterXSize(), ds->GetRasterYSize(), rgba.data() + c, int(texels), int(texels),
        GDT_Byte, 4, GSpacing(texels) * 4, &extra);
    if (e != CE_None) return fail("GDAL cannot decode its pixels");
  }
  // GDAL reads the top row first; GL's row 0 is t = 0, the bottom.
  const std::size_t row = std::size_t(texels) * 4;
  for (std::size_t a = 0, b = texels - 1; a < b; ++a, --b) {
    std::swap_ranges(rgba.begin() + std::ptrdiff_t(a * row), rgba.begin() + std::ptrdiff_t((a + 1) * row),
                     rgba.begin() + std::ptrdiff_t(b * row));
  }
  return rgba;
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

}  // namespace sandtable::runtime::detail
