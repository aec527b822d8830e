#pragma once
// Library messages name option fields ("ViewOptions::hfovDeg"); a user of
// the CLI wants the flag that sets it ("--fov"). One table maps them.
#include <string>

namespace sandtable::cli {

/// `message` with every option field the table knows replaced by its flag.
std::string withFlags(std::string message);
/// The flag that sets `field` exactly ("ElevationOptions::crs" -> "--crs"),
/// or "" when the CLI has none.
std::string flagFor(const std::string& field);

}  // namespace sandtable::cli
