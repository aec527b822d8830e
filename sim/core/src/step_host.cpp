// The fixed-step runner shared by `sim`, the viewer and `bench sim`.
#include "sandtable/sim/step_host.h"

#include <chrono>
#include <cmath>
#include <thread>

#include "sandtable/sim/simulation.h"

namespace sandtable::sim {
namespace {

class SteadyPaceClock final : public PaceClock {
 public:
  double nowS() override {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  }
  void sleepUntilS(double s) override {
    const auto at = std::chrono::steady_clock::time_point(
        std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(s)));
    std::this_thread::sleep_until(at);
  }
};

}  // namespace

PaceClock& steadyPaceClock() {
  static SteadyPaceClock clock;
  return clock;
}

void StepHost::setPacing(Pacing pacing, PaceClock* clock) {
  pacing_ = pacing;
  clock_ = clock;
}

std::uint64_t StepHost::stepsFor(double seconds) const {
  if (!(seconds > 0) || !std::isfinite(seconds)) return 0;
  return static_cast<std::uint64_t>(std::llround(seconds / sim_.options().stepS));
}

void StepHost::step() {
  for (const Hook& h : before_) h(sim_);
  sim_.step();
  for (const Hook& h : after_) h(sim_);
}

StepRun StepHost::runToStep(std::uint64_t totalSteps) {
  StepRun run;
  PaceClock* clock = pacing_ == Pacing::realTime ? (clock_ ? clock_ : &steadyPaceClock()) : nullptr;
  const double start = clock ? clock->nowS() : 0.0;
  const double stepS = sim_.options().stepS;
  while (sim_.steps() < totalSteps) {
    if (cancelled()) {
      run.cancelled = true;
      return run;
    }
    if (clock) {
      // Step k of the run ends at start + (k + 1) stepS of simulated time:
      // it is not taken before then.
      const double due = start + double(run.steps + 1) * stepS;
      if (clock->nowS() < due) {
        clock->sleepUntilS(due);
        if (cancelled()) {
          run.cancelled = true;
          return run;
        }
      }
    }
    step();
    ++run.steps;
  }
  return run;
}

StepRun StepHost::runFor(double seconds) { return runToStep(sim_.steps() + stepsFor(seconds)); }

}  // namespace sandtable::sim
