#pragma once
// `sandtable edits bake DB J -o DB2` (docs/DYNAMIC.md, "Baking"): a new
// database with the edits built in. The grid holds the edited posts (and
// their normals); every module an edit touched is re-meshed from them with
// the shared meshing code (edits/modules.h) and the rest are copied record
// for record in meaning (decoded and encoded again in the newest module
// version); icons, materials and the rest of the files carry over; the
// manifest names the journal and the number of edits baked. Written in a
// staging directory beside the output and renamed into place, as `build`
// does, so an interrupted bake leaves nothing torn.
//
// What the posts cannot carry is not baked: a crater smaller than two posts
// lives in refined squares (height_field.h), which the grid file has no
// place for; the baked database holds it as its posts and lattice planes
// show it (at its depth only where it covers a post), and the journal stays
// the record of it. docs/LIMITATIONS.md says so.
//
// Thread safety: one call at a time per output directory; uses the job
// system's workers.
#include <cstdint>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/base/work.h"
#include "sandtable/formats/edit.h"
#include "sandtable/paging/world.h"

namespace sandtable::edits {

struct BakeReport {
  std::string output;
  std::uint64_t edits = 0;           ///< applied
  std::uint64_t modulesRemeshed = 0;
  std::uint64_t modules = 0;         ///< written
  std::uint64_t gridBytes = 0, packBytes = 0;
  double seconds = 0;
};

/// Bakes `edits` (applied in key order, editor.h) over `base` into the
/// database directory `output`, which must not exist (or, with `replace`,
/// is replaced atomically). Problems name the output or the edit refused.
Result<BakeReport> bake(const paging::World& base, const std::vector<edit::Edit>& edits, const std::string& output,
                        bool replace = false, const Work& work = {});

}  // namespace sandtable::edits
