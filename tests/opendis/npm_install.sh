#!/usr/bin/env bash
# The OpenDis.npmInstall fixture: installs the packages package-lock.json
# pins (open-dis 1.3.6 and its dependencies) into DEST/node_modules, a folder
# of the build tree. Once: a DEST installed from the same lock is left as it
# is, so later runs need no network. Fails, naming the cause, without node,
# npm or the registry. Usage: npm_install.sh SOURCE_DIR DEST
set -euo pipefail
src=$1
dest=$2
for tool in node npm; do
  command -v "$tool" >/dev/null 2>&1 || { echo "opendis: $tool is missing: run tools/setup.sh (docs/INSTALL.md)" >&2; exit 1; }
done
stamp=$dest/node_modules/.sandtable-package-lock.json
if cmp -s "$src/package-lock.json" "$stamp" && [ -f "$dest/node_modules/open-dis/package.json" ]; then
  echo "opendis: $dest/node_modules already holds what package-lock.json pins"
  exit 0
fi
mkdir -p "$dest"
cp "$src/package.json" "$src/package-lock.json" "$dest/"
(cd "$dest" && npm ci --no-audit --no-fund)
version=$(node -p "require('$dest/node_modules/open-dis/package.json').version")
[ "$version" = "1.3.6" ] || { echo "opendis: npm installed open-dis $version, not 1.3.6" >&2; exit 1; }
cp "$src/package-lock.json" "$stamp"
echo "opendis: open-dis $version installed in $dest/node_modules (node $(node --version), npm $(npm --version))"
