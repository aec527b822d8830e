#pragma once
// When a dead-reckoned copy of an entity must be refreshed: the one rule
// behind the script recorder's lines (seed VIII.B.2) and the DIS
// publisher's Entity State PDUs (seed X.C: "when the error exceeds the
// threshold, or a heartbeat is due"). Both keep the copy a receiver would
// dead reckon from their last update and offer it the true state every
// step; this says whether that step sends.
//
// Thread safety: a pure function.
namespace sandtable::sim {

struct UpdateThresholds {
  double positionM = 1.0;   ///< the copy's position error, metres
  double angleDeg = 3.0;    ///< the copy's largest angle error, degrees
  double heartbeatS = 5.0;  ///< at least this often; <= 0: no heartbeat
};

/// True when the copy has drifted past a threshold or a heartbeat is due
/// (`sinceLastS` seconds since the last update; within 1e-9 s of the
/// heartbeat counts as due, so a heartbeat a whole number of steps long is
/// not missed to rounding).
inline bool updateDue(const UpdateThresholds& t, double positionErrorM, double angleErrorDeg, double sinceLastS) {
  if (t.heartbeatS > 0 && sinceLastS >= t.heartbeatS - 1e-9) return true;
  return positionErrorM > t.positionM || angleErrorDeg > t.angleDeg;
}

}  // namespace sandtable::sim
