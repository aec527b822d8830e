// Finding, opening and checking elevation sources.
#include <glob.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <mutex>

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include "elevation_internal.h"
#include "sandtable/base/jobs.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::convert {
namespace fs = std::filesystem;

namespace {

bool hasRasterExtension(const fs::path& p) {
  std::string name = p.filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
  static const char* kExt[] = {".dt0", ".dt1", ".dt2", ".hgt", ".hgt.zip", ".dem",
                               ".tif", ".tiff", ".img", ".asc", ".bil",  ".vrt"};
  for (const char* e : kExt) {
    const std::string ext = e;
    if (name.size() > ext.size() && name.compare(name.size() - ext.size(), ext.size(), ext) == 0) return true;
  }
  return false;
}

Result<std::vector<std::string>> expandDirectory(const std::string& dir) {
  std::vector<std::string> found;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    if (it->is_regular_file(ec) && hasRasterExtension(it->path())) found.push_back(it->path().string());
  }
  if (ec) return Problem{dir, 0, "source: cannot list directory: " + ec.message()};
  if (found.empty()) {
    return Problem{dir, 0, "source: no elevation files (.dt0/.dt1/.dt2/.hgt/.hgt.zip/.dem/.tif) in this "
                           "directory; give the files or the DTED tree's root"};
  }
  std::sort(found.begin(), found.end());
  return found;
}

Result<std::vector<std::string>> expandGlob(const std::string& pattern) {
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
  std::vector<std::string> found;
  if (rc == 0) {
    for (std::size_t k = 0; k < g.gl_pathc; ++k) found.emplace_back(g.gl_pathv[k]);
  }
  ::globfree(&g);
  if (found.empty()) return Problem{pattern, 0, "source: the pattern matches no file"};
  return found;
}

}  // namespace

Result<std::vector<std::string>> expandSources(const std::vector<std::string>& args) {
  if (args.empty()) return Problem{"ElevationOptions::sources", 0, "source: no elevation source given"};
  std::vector<std::string> out;
  for (const auto& a : args) {
    std::error_code ec;
    Result<std::vector<std::string>> part = std::vector<std::string>{};
    if (detail::isGdalVirtual(a)) {
      // A web server's or a bucket's file: GDAL's to find, and not expanded.
      initGdal();
      VSIStatBufL st{};
      if (VSIStatExL(a.c_str(), &st, VSI_STAT_EXISTS_FLAG) != 0) {
        return Problem{a, 0, "source: GDAL finds no file at this virtual path (" + lastGdalError() +
                                 "); check the URL or bucket and that the server is up"};
      }
      part = std::vector<std::string>{a};
    } else if (a.find_first_of("*?[") != std::string::npos && !fs::exists(a, ec)) {
      part = expandGlob(a);
    } else if (fs::is_directory(a, ec)) {
      part = expandDirectory(a);
    } else if (fs::exists(a, ec)) {
      part = std::vector<std::string>{a};
    } else {
      return Problem{a, 0, "source: file not found; check the path"};
    }
    if (!part) return part.problems();
    for (auto& p : part.value()) {
      if (std::find(out.begin(), out.end(), p) == out.end()) out.push_back(p);
    }
  }
  return out;
}

namespace detail {

Result<FileCrc> crcThroughGdal(const std::string& path, const std::string& kind) {
  VSILFILE* f = VSIFOpenL(path.c_str(), "rb");
  if (!f) return Problem{path, 0, kind + ": cannot open the file (" + lastGdalError() + ")"};
  FileCrc out;
  std::vector<std::byte> buf(1 << 20);
  for (;;) {
    const std::size_t n = VSIFReadL(buf.data(), 1, buf.size(), f);
    if (n == 0) break;
    out.crc = crc32(std::span(buf.data(), n), out.crc);
    out.bytes += n;
  }
  // A read that stopped before the end is an error (a server gone mid-file).
  const bool failed = VSIFEofL(f) == 0;
  VSIFCloseL(f);
  if (failed) return Problem{path, out.bytes, kind + ": cannot read the file (" + lastGdalError() + ")"};
  return out;
}

namespace {

/// Lon/lat box of a raster's posts.
bool footprintLonLat(GDALDataset& ds, const std::array<double, 6>& g, std::array<double, 4>& box) {
  const OGRSpatialReference* srs = ds.GetSpatialRef();
  OGRSpatialReference wgs;
  wgs.SetWellKnownGeogCS("WGS84");
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  OGRSpatialReference src(*srs);
  src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&src, &wgs));
  if (!ct) return false;
  std::vector<double> xs, ys;
  const int w = ds.GetRasterXSize(), h = ds.GetRasterYSize();
  for (int k = 0; k <= 32; ++k) {
    const double t = k / 32.0;
    // Outermost post centres, not pixel edges: no target post may need
    // data from beyond the last source post.
    const double x = 0.5 + t * (w - 1), y = 0.5 + t * (h - 1);
    const double edge[4][2] = {{x, 0.5}, {x, h - 0.5}, {0.5, y}, {w - 0.5, y}};
    for (const auto& e : edge) {
      xs.push_back(g[0] + e[0] * g[1] + e[1] * g[2]);
      ys.push_back(g[3] + e[0] * g[4] + e[1] * g[5]);
    }
  }
  if (!ct->Transform(static_cast<int>(xs.size()), xs.data(), ys.data())) return false;
  box = {*std::min_element(xs.begin(), xs.end()), *std::min_element(ys.begin(), ys.end()),
         *std::max_element(xs.begin(), xs.end()), *std::max_element(ys.begin(), ys.end())};
  return std::isfinite(box[0]) && std::isfinite(box[1]) && std::isfinite(box[2]) && std::isfinite(box[3]);
}

/// Reads the first and the last block of the raster, so a truncated file
/// (DTED and SRTM lose their east or south end) fails here, by name, before
/// anything is written. Damage in the middle is caught when the build reads
/// that part, with GDAL's message.
Result<bool> probeEnds(GDALRasterBand& band, const std::string& path) {
  int bw = 0, bh = 0;
  band.GetBlockSize(&bw, &bh);
  const int w = band.GetXSize(), h = band.GetYSize();
  bw = std::clamp(bw, 1, w);
  bh = std::clamp(bh, 1, h);
  std::vector<float> buf(std::size_t(bw) * bh);
  const int corners[2][2] = {{0, 0}, {(w - 1) / bw * bw, (h - 1) / bh * bh}};
  for (const auto& c : corners) {
    const int cw = std::min(bw, w - c[0]), ch = std::min(bh, h - c[1]);
    if (band.RasterIO(GF_Read, c[0], c[1], cw, ch, buf.data(), cw, ch, GDT_Float32, 0, 0) != CE_None) {
      return Problem{path, 0, "source: cannot read the posts at column " + std::to_string(c[0]) + ", row " +
                                  std::to_string(c[1]) + ": " + lastGdalError() + " (the file is truncated or corrupt)"};
    }
  }
  return true;
}

Result<Source> openOne(const std::string& path, bool checksum) {
  Source s;
  s.path = isGdalVirtual(path) ? path : fs::absolute(path).lexically_normal().string();
  if (checksum) {
    const auto crc = crcThroughGdal(path, "source");
    if (!crc) return crc.problems();
    s.crc = crc->crc;
    s.bytes = crc->bytes;
  } else {
    VSIStatBufL st{};
    if (VSIStatExL(path.c_str(), &st, VSI_STAT_SIZE_FLAG) != 0) {
      return Problem{path, 0, "source: cannot read the file: " + lastGdalError()};
    }
    s.bytes = std::uint64_t(st.st_size);
  }
  CPLErrorReset();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) {
    return Problem{path, 0, "source: GDAL cannot open this as a raster (" + lastGdalError() +
                                "); give DTED, SRTM .hgt, USGS DEM, GeoTIFF or another GDAL raster"};
  }
  s.driver = ds->GetDriver() ? ds->GetDriver()->GetDescription() : "";
  if (ds->GetRasterCount() < 1) return Problem{path, 0, "source: the dataset has no raster band"};
  if (ds->GetGeoTransform(s.geo.data()) != CE_None || s.geo[1] == 0 || s.geo[5] == 0) {
    return Problem{path, 0, "source: no georeferencing (geotransform); elevation files must be georeferenced"};
  }
  if (s.geo[2] != 0 || s.geo[4] != 0) return Problem{path, 0, "source: rotated rasters are not supported"};
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  if (!srs) return Problem{path, 0, "source: no coordinate reference system; add one with gdal_edit.py -a_srs"};
  s.geographic = srs->IsGeographic();
  char* wkt = nullptr;
  srs->exportToWkt(&wkt);
  s.srsWkt = wkt ? wkt : "";
  CPLFree(wkt);
  s.width = ds->GetRasterXSize();
  s.height = ds->GetRasterYSize();
  if (!footprintLonLat(*ds, s.geo, s.lonLatBox)) {
    return Problem{path, 0, "source: cannot transform the footprint to lon/lat"};
  }
  if (s.width < 2 || s.height < 2) {
    return Problem{path, 0, "source: the raster is " + std::to_string(s.width) + " x " + std::to_string(s.height) +
                                " posts; at least 2 x 2 are needed"};
  }
  if (auto ok = probeEnds(*ds->GetRasterBand(1), path); !ok) return ok.problems();
  return s;
}

}  // namespace

Result<std::vector<Source>> openSources(const std::vector<std::string>& paths, int threads,
                                        const ProgressFn& progress, bool checksums) {
  initGdal();
  std::vector<std::optional<Result<Source>>> results(paths.size());
  std::size_t done = 0;
  std::mutex progressMutex;
  jobs::parallelFor(paths.size(), threads, [&](std::size_t k) {
    if (cancelRequested()) return;
    results[k].emplace(openOne(paths[k], checksums));
    std::lock_guard lock(progressMutex);
    if (progress) progress(double(++done) / double(paths.size()), "reading sources");
  });
  if (cancelRequested()) return Problem{"build", 0, "build: cancelled"};
  std::vector<Source> out;
  std::vector<Problem> problems;
  for (auto& r : results) {
    if (!r->ok()) problems.insert(problems.end(), r->problems().begin(), r->problems().end());
    else out.push_back(r->value());
  }
  if (!problems.empty()) return problems;
  return out;
}

std::array<double, 2> postMetres(const std::array<double, 6>& geo, bool geographic, double latDeg) {
  double mx = std::fabs(geo[1]), my = std::fabs(geo[5]);
  if (geographic) {
    // Metres per degree on the WGS 84 ellipsoid (series expansion).
    const double lat = latDeg * M_PI / 180.0;
    mx *= 111412.84 * std::cos(lat) - 93.5 * std::cos(3 * lat);
    my *= 111132.954 - 559.822 * std::cos(2 * lat) + 1.175 * std::cos(4 * lat);
  }
  return {mx, my};
}

double nativeSpacingMetres(const std::vector<Source>& sources) {
  double best = INFINITY;
  for (const auto& s : sources) {
    const auto m = postMetres(s.geo, s.geographic, 0.5 * (s.lonLatBox[1] + s.lonLatBox[3]));
    best = std::min({best, m[0], m[1]});
  }
  return best;
}

}  // namespace detail
}  // namespace sandtable::convert
