#pragma once
// Constants shared by the simulator's models.
//
// Thread safety: constants only.
namespace sandtable::sim {

inline constexpr double kDegToRad = 0.017453292519943295;
inline constexpr double kRadToDeg = 57.29577951308232;
/// Standard gravity, m/s^2.
inline constexpr double kGravity = 9.80665;

}  // namespace sandtable::sim
