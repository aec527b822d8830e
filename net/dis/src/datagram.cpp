#include "sandtable/dis/datagram.h"

namespace sandtable::dis {

std::string Address::text() const {
  return std::to_string(ip >> 24) + "." + std::to_string((ip >> 16) & 255) + "." + std::to_string((ip >> 8) & 255) +
         "." + std::to_string(ip & 255) + ":" + std::to_string(port);
}

}  // namespace sandtable::dis
