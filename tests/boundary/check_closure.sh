#!/usr/bin/env bash
# Usage: check_closure.sh EXECUTABLE
# Fails (exit 1) when the executable's link closure, every shared library
# it needs directly or through another, is a GL, EGL, epoxy, X11 or libpng
# library. The probe is linked with --no-as-needed, so every library on
# its link line shows up here, used or not.
set -euo pipefail
exe=$1
forbidden='lib(EGL|GL|GLX|GLdispatch|OpenGL|epoxy|X11|xcb|Xext|Xtst|png16|png)\.so'
closure=$(ldd "$exe" | awk '{print $1}')
bad=$(grep -E "^${forbidden}" <<<"$closure" || true)
if [ -n "$bad" ]; then
  echo "boundary: $exe links a window-system or GL library:"
  echo "$bad" | sed 's/^/  /'
  echo "boundary: base, formats, meshing, icons, world, paging, scene and sim must stay GL-free (docs/ARCHITECTURE.md, section 1)"
  exit 1
fi
echo "boundary: $exe: $(wc -l <<<"$closure") libraries, none of GL, EGL, epoxy, X11 or libpng"
