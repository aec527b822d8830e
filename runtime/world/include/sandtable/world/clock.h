#pragma once
// The application's fixed-step clock: wall time in, whole simulation steps
// out. The world (the key controller today, entities and dynamics next)
// advances only in steps of stepS, so what it does does not depend on the
// frame rate; the viewer draws snapshots of it.
//
// One long frame (a stall, a screenshot written) must not make the world
// jump: at most maxFrameS of wall time counts per call, so below that
// rate the simulation slows down instead (defaults: 1/60 s steps, 0.1 s).
//
// Thread safety: a plain value type; one clock per thread.
#include <cstdint>

namespace sandtable::world {

class FixedStepClock {
 public:
  explicit FixedStepClock(double stepS = 1.0 / 60.0, double maxFrameS = 0.1);

  /// Adds `wallS` seconds of wall time (clamped to [0, maxFrameS]); returns
  /// how many steps the world must advance now. The remainder carries over.
  std::uint32_t advance(double wallS);

  double stepS() const { return step_; }
  /// Simulated time: steps taken times stepS.
  double timeS() const { return double(steps_) * step_; }
  std::uint64_t steps() const { return steps_; }

 private:
  double step_, maxFrame_;
  double carry_ = 0;
  std::uint64_t steps_ = 0;
};

}  // namespace sandtable::world
