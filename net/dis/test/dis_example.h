#pragma once
// The Entity State PDU of docs/DIS.md §3, shared by the golden-bytes test
// and the Wireshark test.
#include "sandtable/dis/pdu.h"

namespace sandtable::dis::testexample {

// The example of docs/DIS.md §3: a T-72 (1.1.225.1.1.3.0) with a turret
// azimuth and one attached store, every field a value whose IEEE 754 bits
// are easy to write down.
inline EntityState example() {
  EntityState e;
  e.id = {1, 2, 0x0304};
  e.force = 2;
  e.type = {1, 1, 225, 1, 1, 3, 0};
  e.velocity = {1.0f, -0.5f, 2.5f};
  e.location = {1024.0, -2.0, 3.0};
  e.orientation = {0.5f, -1.0f, 0.25f};
  e.appearance = 0x18;  // damage bits 3-4: 3, destroyed
  e.deadReckoning.algorithm = 4;
  e.deadReckoning.acceleration = {0, 0, -2.0f};
  e.deadReckoning.angularVelocity = {0, 0.125f, 0};
  e.marking = Marking::ascii("T72 A");
  e.parameters.push_back(toParameter(ArticulatedPart{1, 0, 4096 + 11, 1.5f}));
  e.parameters.push_back(toParameter(AttachedPart{0, 0, 1, {2, 9, 225, 2, 1, 0, 0}}));
  return e;
}

inline Header exampleHeader() {
  Header h;
  h.version = 7;
  h.exercise = 3;
  h.timestamp = timestamp(1800.0, true);
  return h;
}

}  // namespace sandtable::dis::testexample
