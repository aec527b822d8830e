#pragma once
// Helpers shared by the viewer's integration tests.
#include <cstdint>
#include <optional>
#include <string>

#include "sandtable/converters/crs.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/formats/database.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/render/image.h"
#include "test_support.h"

namespace sandtable::test {

/// The clear colour the crack and hole tests draw against (FlightOptions::clearColour).
inline bool isMagenta(const render::Image& img, std::uint32_t x, std::uint32_t y) {
  const auto c = img.at(x, y);
  return c.r > 240 && c.g < 16 && c.b > 240;
}

/// Magenta pixels below the terrain's silhouette: in each column, those
/// under the first pixel from the top that is not the clear colour. With
/// the sky off, each one is a crack or a hole in the terrain.
inline std::uint64_t holesBelowTheSilhouette(const render::Image& img) {
  std::uint64_t n = 0;
  for (std::uint32_t x = 0; x < img.width; ++x) {
    std::uint32_t y = 0;
    while (y < img.height && isMagenta(img, x, y)) ++y;
    for (; y < img.height; ++y) n += isMagenta(img, x, y);
  }
  return n;
}

/// Opens the database in `dir` and starts `o` over (lon, lat), through the
/// database's own CRS. Empty (with a test failure) when either fails.
inline std::optional<Database> openAt(const std::string& dir, double lon, double lat,
                                      viewer::FlightOptions& o) {
  auto db = openDatabase(dir);
  if (!db.ok()) {
    ADD_FAILURE() << db.error();
    return std::nullopt;
  }
  auto geo = geodesy::Projection::create(db->manifest.crsWkt);
  const auto en = geo ? geo->toProjected({lon, lat}) : Result<geodesy::EastNorth>(Problem{});
  if (!en) {
    ADD_FAILURE() << dir << ": cannot place " << lon << " " << lat;
    return std::nullopt;
  }
  o.motion.easting = en->easting, o.motion.northing = en->northing;
  return std::move(db.value());
}

}  // namespace sandtable::test
