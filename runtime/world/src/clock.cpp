#include "sandtable/world/clock.h"

#include <algorithm>
#include <cmath>

namespace sandtable::world {

FixedStepClock::FixedStepClock(double stepS, double maxFrameS)
    : step_(stepS > 0 ? stepS : 1.0 / 60.0), maxFrame_(std::max(maxFrameS, step_)) {}

std::uint32_t FixedStepClock::advance(double wallS) {
  if (!(wallS > 0)) return 0;
  carry_ += std::min(wallS, maxFrame_);
  // A hair of tolerance: 1/60 s of wall time is one step, not zero.
  const auto n = static_cast<std::uint32_t>(std::floor(carry_ / step_ + 1e-9));
  carry_ = std::max(0.0, carry_ - n * step_);
  steps_ += n;
  return n;
}

}  // namespace sandtable::world
