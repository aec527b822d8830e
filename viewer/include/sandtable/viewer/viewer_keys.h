#pragma once
// The stealth viewer's keys for entities (docs/VIEWER.md, "Entities (fly
// --scenario)"), beyond the eye's keys of world/controls.h: attach the eye
// to an entity, cycle through them, drive one, all stop, back to the
// stealth eye. The window reports them (x11_window.h); SimSession
// (sim_session.h) acts on them.
//
// Thread safety: plain values.
#include <cstdint>

namespace sandtable::viewer {

enum class ViewerKey : std::uint8_t {
  nextEntity,      ///< Tab: attach the eye to the next entity (by id, munitions skipped)
  previousEntity,  ///< Shift+Tab: the previous one
  stealth,         ///< E: detach; the stealth eye stays where the tethered eye was
  drive,           ///< D: drive the attached entity (else the scenario's driven one); again: stop driving
  allStop,         ///< Space: all stop for the driven (else attached) entity (seed VII.D)
};

/// "NextEntity", "AllStop", ... for logs and test messages.
const char* viewerKeyName(ViewerKey k);

}  // namespace sandtable::viewer
