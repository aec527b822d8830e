// libFuzzer target: dis::decode (docs/DIS.md) on arbitrary datagrams. A PDU
// that decodes must encode back to the same bytes, bar the protocol family
// (byte 3: the decoder takes any, the encoder writes the type's) and bytes
// 10-11 (version 6's padding, version 7's status and padding, which a
// version 6 encoding writes as zeros); anything else is a bug and traps.
// Run by tools/fuzz.sh with the golden Entity State PDU as the seed.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>

#include "sandtable/dis/pdu.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable;
  const auto bytes = std::as_bytes(std::span(data, size));
  auto pdu = dis::decode(bytes, "fuzz");
  if (!pdu.ok() || !pdu->entityState) return 0;
  const auto again = dis::encode(pdu->header, *pdu->entityState);
  const std::size_t n = pdu->header.length;
  if (again.size() != n || std::memcmp(again.data(), bytes.data(), 3) != 0 ||
      std::memcmp(again.data() + 4, bytes.data() + 4, 6) != 0 ||
      std::memcmp(again.data() + 12, bytes.data() + 12, n - 12) != 0) {
    __builtin_trap();
  }
  return 0;
}
