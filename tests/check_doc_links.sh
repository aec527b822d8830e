#!/usr/bin/env bash
# Fails when a doc, header or source file names a file that does not exist
# (ctest: docs.links). Checked in every tracked .md, .h, .cpp, .sh, .cmake
# and CMakeLists.txt:
#   - every NAME.md or DIR/NAME.md, resolved against the repository root,
#     the referring file's folder, or docs/ ("FORMAT.md §4" in a header
#     means docs/FORMAT.md);
#   - every path with a file extension that starts at one of the
#     repository's top-level folders (formats/src/pack.cpp), or with ../,
#     resolved against the root or the referring file's folder.
# LIB/NAME.h may name LIB's public header LIB/include/sandtable/LIB/NAME.h.
# Include names (sandtable/formats/pack.h) and folder-relative names
# (src/pack.cpp) are left to the compiler and CMake.
set -u
root="${1:-$(cd "$(dirname "$0")/.." && pwd)}"
cd "$root" || exit 2
# The tracked files; outside a git checkout, every file but build trees.
files() {
  git ls-files 2>/dev/null ||
    find . -type f -not -path './.git/*' -not -path './build*' | sed 's#^\./##'
}
tops=$(files | grep / | cut -d/ -f1 | sort -u | sed "s/\./\\\\./g" | paste -sd"|")
# A reference starts after a space, bracket, quote, backtick, '(' or ','
# (not after '/' or a letter: /tmp/x.md is not one) and ends before a
# character that cannot continue a name (x.hgt is not x.h).
pre='(^|[][[:space:]`"(<,;:*])'
md='[A-Za-z0-9_./-]*[A-Za-z0-9_-]+\.md'
path="((${tops})/|\.\./)[A-Za-z0-9_./-]*[A-Za-z0-9_-]+\.(md|h|cpp|txt|sh|cmake|json|path)"
post='([^A-Za-z0-9_]|$)'
bad=0
while IFS= read -r hit; do
  file=${hit%%:*}
  rest=${hit#*:}
  line=${rest%%:*}
  ref=${rest#*:}
  # A system header (#include <net/if.h>) is not one of ours, though net/ is a top folder.
  if [[ $ref == '<'* ]]; then
    sys=${ref#<}
    [[ -e /usr/include/${sys%>} ]] && continue
  fi
  ref=${ref#[][[:space:]\`\"(<,;:*]}
  [[ $ref =~ [^A-Za-z0-9_]$ ]] && ref=${ref%?}
  [[ -z $ref ]] && continue
  # The test data is not beside this checkout: locally that is allowed (as
  # SANDTABLE_REQUIRE skips), in CI (SANDTABLE_REQUIRE_ALL=1) it still fails.
  if [[ $ref == ../shared/* && ! -d ../shared && -z ${SANDTABLE_REQUIRE_ALL:-} ]]; then
    continue
  fi
  dir=${file%/*}
  [[ $dir == "$file" ]] && dir=.
  lib=${ref%%/*}
  short=$lib/include/sandtable/$lib/${ref#*/}  # base/result.h: a library's public header, for short
  if [[ ! -e $ref && ! -e $dir/$ref && ! -e docs/$ref && ! -e $short ]]; then
    echo "$file:$line: names $ref, which does not exist"
    bad=1
  fi
done < <(files | grep -E '(\.(md|h|cpp|sh|cmake)|CMakeLists\.txt)$' | grep -vx 'tests/check_doc_links.sh' | tr '\n' '\0' |
         xargs -0 grep -HnoE "${pre}(${md}|${path})${post}")
if [[ $bad == 0 ]]; then echo "every file reference resolves"; fi
exit $bad
