// The source mosaic: GDALBuildVRT over the sources, each worker's handle on
// it, and the source image of the posts the target covers, read once for
// all strips block by block (docs/ARCHITECTURE.md, stage 6).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <new>

#include <cpl_string.h>
#include <gdal_utils.h>

#include "elevation_resample.h"

namespace sandtable::convert::detail {

Status buildMosaic(const std::vector<Source>& sources, const std::string& vrtPath) {
  std::vector<const char*> names;
  for (const auto& s : sources) names.push_back(s.path.c_str());
  const char* args[] = {"-resolution", "highest", "-q", nullptr};
  GDALBuildVRTOptions* opts = GDALBuildVRTOptionsNew(const_cast<char**>(args), nullptr);
  int usageError = 0;
  CPLErrorReset();
  GDALDatasetH vrt = GDALBuildVRT(vrtPath.c_str(), static_cast<int>(names.size()), nullptr,
                                  names.data(), opts, &usageError);
  GDALBuildVRTOptionsFree(opts);
  if (!vrt) {
    return stageError("mosaic: cannot build a mosaic of the sources: " + lastGdalError() +
                      " (all sources must share one coordinate system)");
  }
  GDALClose(vrt);
  return {};
}

bool frameScale(const Frame& f, OGRCoordinateTransformation& toSource, const std::array<double, 6>& geo,
                FrameScale& out) {
  double x[4] = {f.originEasting, f.originEasting + (f.postsX - 1) * f.spacing, f.originEasting,
                 f.originEasting + (f.postsX - 1) * f.spacing};
  double y[4] = {f.originNorthing, f.originNorthing, f.originNorthing - (f.postsZ - 1) * f.spacing,
                 f.originNorthing - (f.postsZ - 1) * f.spacing};
  if (!toSource.Transform(4, x, y)) return false;
  out.spanX = (std::max({x[0], x[1], x[2], x[3]}) - std::min({x[0], x[1], x[2], x[3]})) / std::fabs(geo[1]);
  out.spanY = (std::max({y[0], y[1], y[2], y[3]}) - std::min({y[0], y[1], y[2], y[3]})) / std::fabs(geo[5]);
  out.sx = f.postsX / (out.spanX + 1);
  out.sy = f.postsZ / (out.spanY + 1);
  return std::isfinite(out.sx + out.sy) && out.sx > 0 && out.sy > 0;
}

namespace {

/// One source of the VRT mosaic, as GDALBuildVRT writes it.
struct VrtSource {
  std::string path;
  int band = 1;
  int sx = 0, sy = 0, dx = 0, dy = 0, w = 0, h = 0;  // SrcRect origin, DstRect origin, size
  bool hasNoData = false;
  double noData = 0;
};

bool integerAttr(const CPLXMLNode* n, const char* name, int& out) {
  const char* v = CPLGetXMLValue(n, name, nullptr);
  if (!v) return false;
  const double d = CPLAtof(v);
  out = static_cast<int>(std::lround(d));
  return std::fabs(d - out) < 1e-9;
}

/// The sources of band 1 of the VRT in its order, or false when the VRT
/// holds anything but plain unscaled sources (then the VRT itself is read).
bool vrtSources(const std::string& vrtPath, std::vector<VrtSource>& out) {
  CPLXMLNode* root = CPLParseXMLFile(vrtPath.c_str());
  if (!root) return false;
  bool ok = true;
  const CPLXMLNode* ds = CPLGetXMLNode(root, "=VRTDataset");
  const CPLXMLNode* band = nullptr;
  for (const CPLXMLNode* c = ds ? ds->psChild : nullptr; c; c = c->psNext) {
    if (c->eType == CXT_Element && std::string(c->pszValue) == "VRTRasterBand" &&
        std::string(CPLGetXMLValue(c, "band", "1")) == "1") {
      band = c;
    }
  }
  if (!band || CPLGetXMLValue(band, "subClass", nullptr)) ok = false;
  for (const CPLXMLNode* c = band ? band->psChild : nullptr; ok && c; c = c->psNext) {
    if (c->eType != CXT_Element) continue;
    const std::string kind = c->pszValue;
    if (kind != "SimpleSource" && kind != "ComplexSource") {
      if (kind != "NoDataValue" && kind != "ColorInterp" && kind != "Metadata" && kind != "Description") ok = false;
      continue;
    }
    VrtSource v;
    for (const CPLXMLNode* e = c->psChild; e; e = e->psNext) {
      if (e->eType != CXT_Element) continue;
      const std::string n = e->pszValue;
      if (n == "NODATA") {
        v.hasNoData = true;
        v.noData = CPLAtof(CPLGetXMLValue(e, nullptr, "0"));
      } else if (n != "SourceFilename" && n != "SourceBand" && n != "SourceProperties" && n != "SrcRect" &&
                 n != "DstRect") {
        ok = false;  // scaling, LUT, masks, resampling...: leave it to GDAL
      }
    }
    const char* name = CPLGetXMLValue(c, "SourceFilename", nullptr);
    int sw = 0, sh = 0;
    if (!name || !integerAttr(c, "SrcRect.xOff", v.sx) || !integerAttr(c, "SrcRect.yOff", v.sy) ||
        !integerAttr(c, "SrcRect.xSize", sw) || !integerAttr(c, "SrcRect.ySize", sh) ||
        !integerAttr(c, "DstRect.xOff", v.dx) || !integerAttr(c, "DstRect.yOff", v.dy) ||
        !integerAttr(c, "DstRect.xSize", v.w) || !integerAttr(c, "DstRect.ySize", v.h) || sw != v.w || sh != v.h) {
      ok = false;
      break;
    }
    v.band = std::atoi(CPLGetXMLValue(c, "SourceBand", "1"));
    const bool relative = std::atoi(CPLGetXMLValue(c, "SourceFilename.relativeToVRT", "0")) != 0;
    v.path = relative ? CPLProjectRelativeFilename(CPLGetPath(vrtPath.c_str()), name) : name;
    out.push_back(std::move(v));
  }
  CPLDestroyXMLNode(root);
  return ok && !out.empty();
}

/// Reads rect (x, y, w, h) of a source band as floats, row-major. Bands in
/// one-column blocks (DTED) are read block by block: RasterIO would copy
/// them pixel by pixel.
bool readSourceRect(GDALRasterBand& b, int x, int y, int w, int h, std::vector<float>& out) {
  out.resize(std::size_t(w) * h);
  int bw = 0, bh = 0;
  b.GetBlockSize(&bw, &bh);
  if (bw != 1 || bh < 2) {
    return b.RasterIO(GF_Read, x, y, w, h, out.data(), w, h, GDT_Float32, 0, 0) == CE_None;
  }
  const GDALDataType type = b.GetRasterDataType();
  const int bytes = GDALGetDataTypeSizeBytes(type);
  std::vector<std::byte> block(std::size_t(bh) * bytes);
  for (int by = y / bh; by * bh < y + h; ++by) {
    const int r0 = std::max(y, by * bh), r1 = std::min(y + h, (by + 1) * bh);
    for (int c = x; c < x + w; ++c) {
      if (b.ReadBlock(c, by, block.data()) != CE_None) return false;
      GDALCopyWords64(block.data() + std::size_t(r0 - by * bh) * bytes, type, bytes,
                      out.data() + std::size_t(r0 - y) * w + (c - x), GDT_Float32, w * int(sizeof(float)), r1 - r0);
    }
  }
  return true;
}

}  // namespace

/// Fills `image` with the mosaic's posts over the source positions of the
/// posts of grid rows [j0, j1), padded by `pad` posts; leaves it empty (the
/// strips then read the VRT) when the VRT is not plain or the image would be
/// too big.
void buildSourceImage(const std::string& vrtPath, const Frame& f, std::uint32_t j0, std::uint32_t j1, double pad,
                      int threads, SourceImage& image) {
  image = {};
  MosaicReader m;
  if (!m.open(vrtPath, f).empty()) return;
  std::vector<VrtSource> sources;
  if (!vrtSources(vrtPath, sources)) return;
  // Source positions along the frame's edge, every 8 posts.
  std::vector<double> x, y;
  auto add = [&](std::uint32_t i, std::uint32_t j) {
    x.push_back(f.originEasting + i * f.spacing);
    y.push_back(f.originNorthing - j * f.spacing);
  };
  for (std::uint32_t i = 0; i < f.postsX; i += 8) add(i, j0), add(i, j1 - 1);
  for (std::uint32_t j = j0; j < j1; j += 8) add(0, j), add(f.postsX - 1, j);
  add(f.postsX - 1, j0);
  add(f.postsX - 1, j1 - 1);
  add(0, j1 - 1);
  if (!m.toSource->Transform(static_cast<int>(x.size()), x.data(), y.data())) return;
  double xMin = INFINITY, xMax = -INFINITY, yMin = INFINITY, yMax = -INFINITY;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double px = (x[k] - m.geo[0]) / m.geo[1] - 0.5, py = (y[k] - m.geo[3]) / m.geo[5] - 0.5;
    xMin = std::min(xMin, px), xMax = std::max(xMax, px), yMin = std::min(yMin, py), yMax = std::max(yMax, py);
  }
  if (!std::isfinite(xMin + xMax + yMin + yMax)) return;
  GDALRasterBand& band = m.band();
  const int W = band.GetXSize(), H = band.GetYSize();
  const int x0 = std::clamp(static_cast<int>(std::floor(xMin - pad)), 0, W - 1);
  const int y0 = std::clamp(static_cast<int>(std::floor(yMin - pad)), 0, H - 1);
  const int x1 = std::clamp(static_cast<int>(std::ceil(xMax + pad)), 0, W - 1);
  const int y1 = std::clamp(static_cast<int>(std::ceil(yMax + pad)), 0, H - 1);
  const std::size_t n = std::size_t(x1 - x0 + 1) * std::size_t(y1 - y0 + 1);
  // No more than 4 bytes per post of 1 G posts; bigger mosaics go strip by strip.
  if (n > (std::size_t(1) << 30)) return;
  int hasNoData = 0;
  const double nd = band.GetNoDataValue(&hasNoData);
  SourceImage img;
  img.x0 = x0, img.y0 = y0, img.w = x1 - x0 + 1, img.h = y1 - y0 + 1;
  // As VRTSourcedRasterBand: posts no source covers hold the nodata value,
  // or 0. Values are stored as validOrNan of what the VRT would give.
  const float fnd = static_cast<float>(nd);
  const float init = validOrNan(hasNoData ? fnd : 0.0f, hasNoData != 0, fnd);
  img.v.reset(new (std::nothrow) float[n]);
  if (!img.v) return;  // no memory for it: strip by strip
  jobs::parallelRanges(n, threads, std::size_t(1) << 20,
                       [&](std::size_t b, std::size_t e) { std::fill(img.v.get() + b, img.v.get() + e, init); });
  // Sources are read in parallel and composited in the VRT's order (a
  // later source's valid posts replace an earlier one's, as in the VRT);
  // as many are read ahead as there are workers.
  struct Read {
    bool ok = true, empty = false;
    int ax = 0, ay = 0, bx = 0, by = 0;
    std::vector<float> buf;
  };
  bool failed = false;
  jobs::orderedPipeline<Read>(
      sources.size(), threads, std::size_t(jobs::threadCount(threads)),
      [&](std::size_t k) {
        const VrtSource& s = sources[k];
        Read r;
        r.ax = std::max(x0, s.dx), r.ay = std::max(y0, s.dy);
        r.bx = std::min(x1 + 1, s.dx + s.w), r.by = std::min(y1 + 1, s.dy + s.h);
        r.empty = r.ax >= r.bx || r.ay >= r.by;
        if (!r.empty) {
          std::unique_ptr<GDALDataset> ds(GDALDataset::Open(s.path.c_str(), GDAL_OF_RASTER | GDAL_OF_VERBOSE_ERROR));
          GDALRasterBand* b = ds && s.band >= 1 && s.band <= ds->GetRasterCount() ? ds->GetRasterBand(s.band) : nullptr;
          r.ok = b && readSourceRect(*b, s.sx + r.ax - s.dx, s.sy + r.ay - s.dy, r.bx - r.ax, r.by - r.ay, r.buf);
        }
        return r;
      },
      [&](std::size_t k, Read&& r) {
        const VrtSource& s = sources[k];
        if (!r.ok) failed = true;
        if (!r.ok || r.empty || failed) return;
        const int w = r.bx - r.ax;
        const float snd = static_cast<float>(s.noData);
        const bool vnd = hasNoData != 0;
        for (int row = r.ay; row < r.by; ++row) {
          float* dst = img.v.get() + std::size_t(row - y0) * img.w + (r.ax - x0);
          const float* src = r.buf.data() + std::size_t(row - r.ay) * w;
          if (!s.hasNoData) {
            for (int c = 0; c < w; ++c) dst[c] = validOrNan(src[c], vnd, fnd);
          } else {
            for (int c = 0; c < w; ++c) {
              if (!(src[c] == snd || (std::isnan(snd) && std::isnan(src[c])))) dst[c] = validOrNan(src[c], vnd, fnd);
            }
          }
        }
      });
  if (failed) return;  // the strips read the VRT and report its error
  image = std::move(img);
}

}  // namespace sandtable::convert::detail
