#!/usr/bin/env bash
# Installs every Debian package sandtable needs (idempotent, non-interactive)
# and makes a Release build in ./build. Usage: tools/setup.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build}

packages=(
  build-essential cmake ninja-build pkg-config git
  libgdal-dev gdal-bin            # GDAL/OGR with PROJ: every raster and vector source, and its reprojection
  libproj-dev proj-data           # PROJ: geodesy/ (database frame, lon/lat/height, ECEF) links it directly; proj-data holds the EPSG grids (egm96_15.gtx)
  libeigen3-dev                   # vector math
  libtbb-dev                      # oneTBB: the job system of every parallel build stage
  libcgal-dev libgmp-dev libmpfr-dev libboost-dev  # CGAL (exact arithmetic): culture cut to the terrain triangles
  nlohmann-json3-dev              # manifest and --json output
  libcli11-dev                    # subcommand CLI with --help
  zlib1g-dev                      # CRC-32 (and compression)
  libzstd-dev                     # zstd: load modules compressed in modules.pack
  libmeshoptimizer-dev            # meshoptimizer: load module codecs, icon simplification
  libassimp-dev                   # assimp: icon model import (glTF, 3DS, OBJ, OFF, ...)
  libepoxy-dev libegl-dev libegl-mesa0 libgl1-mesa-dri  # OpenGL 4.5 core through EGL (llvmpipe)
  libpng-dev                      # PNG frames and icon textures
  libjpeg-dev                     # JPEG icon textures in the renderer (libjpeg62-turbo; already there with libgdal-dev)
  libx11-dev libxtst-dev xvfb xauth  # stealth viewer window (Xlib + EGL on X11); Xvfb + XTest run its test
  ffmpeg                          # fly --video; installed so its tests run (CI fails a test that would skip)
  libpcap-dev                     # libpcap: DIS capture files, pcap and pcapng (net/dis/)
  libcurl4-openssl-dev            # libcurl: HTTP range reads of databases on a web server (net/http/)
  nginx-light                     # the web server the HTTP tests start on loopback (testing/nginx.h)
  openssl                         # the HTTPS test makes its own certificate for 127.0.0.1
  tshark                          # Wireshark's DIS dissector: an independent reader of our PDUs (net/dis tests)
  clang libclang-rt-dev           # clang with libFuzzer (-fsanitize=fuzzer): tools/fuzz.sh, run by .ci/run
  zstd                            # the zstd tool: tools/fuzz.sh unpacks pack records into module seeds
  slurm-wlm munge                 # a one-node Slurm cluster (tools/slurm-local.sh) for the Slurm tests
  libgtest-dev libgmock-dev libbenchmark-dev  # tests and micro-benchmarks
)

# Node.js and npm run the Open-DIS for JavaScript check (tests/opendis; its
# ctest fixture installs the npm package). Checked by command, not by
# package: a node from elsewhere (NodeSource's nodejs, which bundles npm and
# conflicts with Debian's npm package) is used as it is. Debian 12's nodejs
# is 18 and its npm 9.
if ! command -v node >/dev/null 2>&1; then
  packages+=(nodejs npm)
elif ! command -v npm >/dev/null 2>&1; then
  packages+=(npm)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# ccache, when the machine has it, makes a rebuild in a fresh clone cheap;
# without it the build is the same.
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" ${SANDTABLE_CMAKE_ARGS:-}
cmake --build "$build_dir" -j "$(nproc)"
echo "setup: built $build_dir/tools/sandtable"
