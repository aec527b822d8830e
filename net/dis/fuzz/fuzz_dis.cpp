// libFuzzer target: dis::decode (docs/DIS.md) on arbitrary datagrams. A PDU
// that decodes must encode back to the same bytes, bar the protocol family
// (byte 3: the decoder takes any, the encoder writes the type's), bytes
// 10-11 (version 6's padding, version 7's status and padding, which a
// version 6 encoding writes as zeros), the Detonation PDU's padding
// (102-103), the Point Object State PDU's (84-87) and each linear segment's
// last 4 bytes; anything else is a bug and traps.
// Run by tools/fuzz.sh with the golden PDUs of every decoded type as seeds.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "sandtable/dis/pdu.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace sandtable;
  const auto bytes = std::as_bytes(std::span(data, size));
  auto pdu = dis::decode(bytes, "fuzz");
  if (!pdu.ok()) return 0;
  std::vector<std::byte> again;
  if (pdu->entityState) again = dis::encode(pdu->header, *pdu->entityState);
  else if (pdu->fire) again = dis::encode(pdu->header, *pdu->fire);
  else if (pdu->detonation) again = dis::encode(pdu->header, *pdu->detonation);
  else if (pdu->createEntity) again = dis::encode(pdu->header, *pdu->createEntity);
  else if (pdu->removeEntity) again = dis::encode(pdu->header, *pdu->removeEntity);
  else if (pdu->pointObject) again = dis::encode(pdu->header, *pdu->pointObject);
  else if (pdu->linearObject) again = dis::encode(pdu->header, *pdu->linearObject);
  else return 0;
  const std::size_t n = pdu->header.length;
  if (again.size() != n) __builtin_trap();
  for (std::size_t k = 0; k < n; ++k) {
    // Taken as sent, written as the standard has them: the family, the
    // header's status and padding, and the padding of the Detonation PDU,
    // the Point Object State PDU and each linear segment.
    const bool segmentPadding = pdu->linearObject && k >= dis::kLinearObjectBytes &&
                                (k - dis::kLinearObjectBytes) % dis::kSegmentBytes >= 60;
    const bool free = k == 3 || k == 10 || k == 11 || (pdu->detonation && (k == 102 || k == 103)) ||
                      (pdu->pointObject && k >= 84) || segmentPadding;
    if (!free && again[k] != bytes[k]) __builtin_trap();
  }
  return 0;
}
