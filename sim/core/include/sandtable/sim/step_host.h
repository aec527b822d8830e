#pragma once
// The one owner of the simulation's fixed step (docs/SIM.md §1): `sandtable
// sim`, the viewer (`fly --scenario`) and `bench sim` all advance a
// Simulation through a StepHost, so "how many steps is t seconds", the
// hooks around a step and cancellation are one rule.
//
// A run steps either as fast as it can or paced to real time (no step is
// taken before its simulated end time has passed on the clock, so the
// simulation never runs ahead of the wall; a run that falls behind catches
// up without waiting). Before each step the before-hooks run, after it the
// after-hooks, each list in the order added: the DIS network reads pending
// PDUs before a step and publishes after it. A cancel flag is read before
// every step (and after every wait), so a run stops within one step of it
// being set.
//
// Thread safety: one thread drives a StepHost and its Simulation; the
// cancel flag may be set from any thread or a signal handler. Hooks run on
// the driving thread, between steps, and may change the simulation (add,
// remove or command entities).
#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

namespace sandtable::sim {

class Simulation;

/// The wall clock a paced run waits on. Tests inject a fake one that
/// jumps instead of sleeping.
class PaceClock {
 public:
  virtual ~PaceClock() = default;
  /// Monotonic seconds from an arbitrary origin.
  virtual double nowS() = 0;
  /// Returns at `s` (or as soon after as the system allows).
  virtual void sleepUntilS(double s) = 0;
};

/// std::chrono::steady_clock and std::this_thread::sleep_until. Stateless:
/// safe from any thread.
PaceClock& steadyPaceClock();

enum class Pacing : std::uint8_t {
  asFastAsPossible,  ///< `sandtable sim`, the benchmark, headless flights
  realTime,          ///< step k of a run ends at run start + (k + 1) x stepS on the clock
};

struct StepRun {
  std::uint64_t steps = 0;  ///< steps taken by this run
  bool cancelled = false;   ///< the cancel flag stopped it before its end
};

class StepHost {
 public:
  /// A hook sees the simulation between steps (before: at the step's start
  /// time; after: at its end time).
  using Hook = std::function<void(Simulation&)>;

  explicit StepHost(Simulation& simulation) : sim_(simulation) {}

  void addBeforeStep(Hook hook) { before_.push_back(std::move(hook)); }
  void addAfterStep(Hook hook) { after_.push_back(std::move(hook)); }
  /// Read before every step of a run; null: runs are never cancelled.
  void setCancel(const std::atomic<bool>* cancel) { cancel_ = cancel; }
  /// realTime waits on `clock` (default: steadyPaceClock()).
  void setPacing(Pacing pacing, PaceClock* clock = nullptr);

  /// The steps that make `seconds` of simulated time: round(seconds / stepS),
  /// 0 for a negative or non-finite time.
  std::uint64_t stepsFor(double seconds) const;

  /// One step with its hooks; neither paced nor cancellable.
  void step();
  /// Steps until the simulation has taken `totalSteps` steps in all (a
  /// simulation already there does not move), paced and cancellable.
  StepRun runToStep(std::uint64_t totalSteps);
  /// `stepsFor(seconds)` more steps, paced and cancellable.
  StepRun runFor(double seconds);

  Simulation& simulation() { return sim_; }

 private:
  bool cancelled() const { return cancel_ && cancel_->load(std::memory_order_relaxed); }

  Simulation& sim_;
  std::vector<Hook> before_, after_;
  const std::atomic<bool>* cancel_ = nullptr;
  Pacing pacing_ = Pacing::asFastAsPossible;
  PaceClock* clock_ = nullptr;
};

}  // namespace sandtable::sim
