#!/usr/bin/env bash
# Builds every libFuzzer target with clang (a separate build directory, only
# the fuzz targets and the libraries they need, instrumented for coverage
# and AddressSanitizer) and runs each for a short fixed time on seeds from
# samples/ and a small database built by the normal build's CLI. Any crash,
# leak, sanitizer report or timeout fails the script (exit 1); the input
# that did it is kept under BUILD_DIR/crashes/. Run by .ci/run.
# Usage: tools/fuzz.sh [BUILD_DIR]   (default build-fuzz)
# Environment: SANDTABLE_FUZZ_SECONDS (per target, default 6: 11 targets, about a minute),
#   SANDTABLE_FUZZ_RUNS (most inputs per target, default 200000),
#   SANDTABLE_CLI (the CLI that builds the seed database, default build/tools/sandtable).
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build-fuzz}
seconds=${SANDTABLE_FUZZ_SECONDS:-6}
runs=${SANDTABLE_FUZZ_RUNS:-200000}
cli=${SANDTABLE_CLI:-build/tools/sandtable}

command -v clang++ >/dev/null || { echo "fuzz: clang++ not found (tools/setup.sh installs clang)" >&2; exit 1; }
launcher=()
if command -v ccache >/dev/null 2>&1; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
# Every library is instrumented (fuzzer-no-link) so that libFuzzer sees the
# readers' branches, not only the target's; the targets add -fsanitize=fuzzer.
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ "${launcher[@]}" \
  -DCMAKE_C_FLAGS="-fsanitize=fuzzer-no-link,address" -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link,address" \
  -DSANDTABLE_FUZZ=ON -DSANDTABLE_TESTS=OFF -DSANDTABLE_BENCH=OFF >/dev/null
cmake --build "$build_dir" --target sandtable_fuzzers -j 2

# Seeds: a fresh corpus every run, so a run is the same on every machine.
seeds=$build_dir/seeds
rm -rf "$seeds" "$build_dir/corpus" "$build_dir/crashes"
mkdir -p "$seeds" "$build_dir/crashes"
seed() {  # seed NAME FILE... : copy files into NAME's seed directory
  local name=$1
  shift
  mkdir -p "$seeds/$name"
  for f in "$@"; do cp "$f" "$seeds/$name/"; done
}
seed sandtable_fuzz_materials samples/materials.txt
seed sandtable_fuzz_icon_definitions samples/icons.txt samples/icons-models.txt
seed sandtable_fuzz_path samples/demo.path
# The DIS target starts from the golden bytes of every PDU type it decodes (docs/DIS.md §3-3.5):
# Entity State, Fire and Detonation first.
mkdir -p "$seeds/sandtable_fuzz_dis"
python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes.fromhex(''.join(sys.argv[2:])))" \
  "$seeds/sandtable_fuzz_dis/entity-state" \
  070301018000000100b000000001000203040202010100e10101030000000000000000003f800000bf000000 \
  402000004090000000000000c00000000000000040080000000000003f000000bf8000003e80000000000018 \
  040000000000000000000000000000000000000000000000c0000000000000003e0000000000000001543732 \
  204100000000000000000000000100000000100b3fc00000000000000100000000000001020900e102010000
python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes.fromhex(''.join(sys.argv[2:])))" \
  "$seeds/sandtable_fuzz_dis/fire" \
  0703020280000001006000000001000200030001000200040000000000000001000200090000000040900000 \
  00000000c0000000000000004008000000000000020900e10201000003e803e8000100003f800000bf000000 \
  4020000040000000
python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes.fromhex(''.join(sys.argv[2:])))" \
  "$seeds/sandtable_fuzz_dis/detonation" \
  0703030280000001007800000001000200030001000200040000000000000001000200093f800000bf000000 \
  402000004090000000000000c0000000000000004008000000000000020900e10201000003e803e800010000 \
  3f000000bf8000003e80000001010000000000000000100b3fc0000000000000
# Create Entity (docs/DIS.md §3.3; Remove Entity is the same with byte 2 = 0c), Point Object
# State (§3.4) and Linear Object State (§3.5), the golden bytes of test_pdu.cpp.
python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes.fromhex(''.join(sys.argv[2:])))" \
  "$seeds/sandtable_fuzz_dis/create-entity" \
  07030b0580000001001c00000001000300000001000203040a0b0c0d
python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes.fromhex(''.join(sys.argv[2:])))" \
  "$seeds/sandtable_fuzz_dis/remove-entity" \
  07030c0580000001001c00000001000300000001000203040a0b0c0d
python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes.fromhex(''.join(sys.argv[2:])))" \
  "$seeds/sandtable_fuzz_dis/point-object" \
  07032b09800000010058000000010002001100000000000000050101010203044090000000000000c0000000 \
  0000000040080000000000003f000000bf8000003e800000010203040506070800010002ffffffff00000000
python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes.fromhex(''.join(sys.argv[2:])))" \
  "$seeds/sandtable_fuzz_dis/linear-object" \
  07032c098000000100a800000001000200120000000000000001020200010002ffffffff0105020101001234 \
  89abcdef4090000000000000c00000000000000040080000000000003f000000bf8000003e80000042c80000 \
  40800000402000003f00000000000000020100000000000040a0000000000000c00000000000000040080000 \
  000000000000000000000000000000004248000040800000000000000000000000000000
# The journal target starts from the golden journal (docs/FORMAT.md §14.6): the header, a crater
# and a berm in one write.
mkdir -p "$seeds/sandtable_fuzz_journal"
python3 -c "import sys; open(sys.argv[1], 'wb').write(bytes.fromhex(''.join(sys.argv[2:])))" \
  "$seeds/sandtable_fuzz_journal/golden" \
  53414e444a524e4c01000000180000000000000073647a07750000001800000000000000b0f0e4406af4e8a7 \
  0100000000000000000000000000294002000100010000000000000840000000000000f83f00000000000000 \
  000000000000000000000000000000000000000000000000000000000000000000f03f000000000000000000 \
  0000000000000002000100000000000000000059400000000000006940850000001800000000000000736240 \
  20449fc53902000000000000000000000000002a400000000002000000000000000000000000000000000000 \
  000000000040000000000000f83f000000000000e03f00000000000000000000000000000000f03f00000000 \
  00000000000000000000000000000200000000000000000020c0000000000000104000000000000038400000 \
  000000001040
# The sim text target's first byte picks the reader: 0 script, 1 scenario,
# 2 aircraft, 3 collision table.
mkdir -p "$seeds/sandtable_fuzz_sim_text"
pick() { { printf "\\x$1"; cat "$2"; } >"$seeds/sandtable_fuzz_sim_text/$1-$(basename "$2")"; }
pick 00 samples/demo.script
pick 01 samples/demo.scenario
pick 01 samples/terrain.scenario
for f in samples/aircraft/*.txt; do pick 02 "$f"; done
pick 03 samples/collisions.txt

# A small database (Monaco, 1.6 km by 1.7 km at 30 m: one grid block, with icons and materials)
# seeds the binary readers.
data=../shared/data/elevation/srtm/N43E007.hgt.zip
if [ -x "$cli" ] && [ -f "$data" ]; then
  db=$build_dir/seed-db
  "$cli" build --elevation "$data" --extent 7.40 43.725 7.42 43.74 --spacing 30 \
    --icons samples/icons.txt --materials samples/materials.txt -o "$db" --force >/dev/null 2>&1
  seed sandtable_fuzz_grid "$db/grid.stg"
  seed sandtable_fuzz_manifest "$db/manifest.json"
  seed sandtable_fuzz_icon_pack "$db/icons.pack"
  # A build part (docs/FORMAT.md §15): the same area planned as one task and built.
  rm -rf "$build_dir/seed-parts"
  if "$cli" build --elevation "$data" --extent 7.40 43.725 7.42 43.74 --spacing 30 -o "$build_dir/seed-dist" \
      --plan "$build_dir/seed-plan.json" --parts "$build_dir/seed-parts" --tasks 1 >/dev/null 2>&1 &&
    "$cli" build --task "$build_dir/seed-plan.json" 0 >/dev/null 2>&1; then
    seed sandtable_fuzz_part "$build_dir/seed-parts/part-00000.stp"
  fi
  mkdir -p "$seeds/sandtable_fuzz_pack"
  python3 - "$db" "$seeds/sandtable_fuzz_pack/db" <<'EOF'
import struct, sys
idx = open(sys.argv[1] + "/modules.idx", "rb").read()
pack = open(sys.argv[1] + "/modules.pack", "rb").read()
open(sys.argv[2], "wb").write(struct.pack("<I", len(idx)) + idx + pack)
EOF
  # Raw modules (the pack's first records, coarse and fine, unpacked by the zstd tool) seed the
  # module target: version 6 from the default build (rules regenerated in the fine records, kept
  # by bitmap in the coarse ones) and version 5 from a second build (every object stored).
  "$cli" build --elevation "$data" --extent 7.40 43.725 7.42 43.74 --spacing 30 --module-version 5 \
    --icons samples/icons.txt --materials samples/materials.txt -o "$db-v5" --force >/dev/null 2>&1 || true
  if command -v zstd >/dev/null 2>&1; then
    for d in "$db" "$db-v5"; do
      [ -f "$d/modules.idx" ] || continue
      python3 - "$d" "$seeds/sandtable_fuzz_module" "$(basename "$d")" <<'EOF'
import os, struct, subprocess, sys
db, out, tag = sys.argv[1], sys.argv[2], sys.argv[3]
os.makedirs(out, exist_ok=True)
idx = open(db + "/modules.idx", "rb").read()
pack = open(db + "/modules.pack", "rb").read()
entry_bytes, count, table = struct.unpack_from("<IQQ", idx, 52)  # FORMAT.md §10: entryBytes, entryCount, tableOffset
for k in range(min(count, 2)):
    records = [struct.unpack_from("<QI", idx, table + k * entry_bytes)]
    if entry_bytes == 64:  # v2: the fine record too
        records.append(struct.unpack_from("<QI", idx, table + k * entry_bytes + 24))
    for r, (offset, size) in enumerate(records):
        if size == 0:
            continue
        raw = subprocess.run(["zstd", "-dcq"], input=pack[offset:offset + size], capture_output=True)
        if raw.returncode == 0:
            open(f"{out}/{tag}-module{k}-{r}", "wb").write(raw.stdout)
EOF
    done
  fi
else
  echo "fuzz: warning: no $cli or no $data; the binary readers start from empty seeds" >&2
fi

# The grid and pack targets write their scratch files under TMPDIR.
export TMPDIR="$(cd "$build_dir" && pwd)/tmp"
rm -rf "$TMPDIR"
mkdir -p "$TMPDIR"
status=0
while read -r name bin; do
  corpus=$build_dir/corpus/$name
  mkdir -p "$corpus" "$seeds/$name"
  echo "fuzz: $name for ${seconds} s (at most $runs inputs)"
  # -timeout: one input taking 10 s is a hang; -rss_limit_mb: an input that
  # makes a reader allocate over 2 GiB is a failure too.
  if ! "$bin" -max_total_time="$seconds" -runs="$runs" -timeout=10 -rss_limit_mb=2048 \
      -artifact_prefix="$build_dir/crashes/$name-" -print_final_stats=0 "$corpus" "$seeds/$name" \
      >"$build_dir/$name.log" 2>&1; then
    echo "fuzz: $name FAILED; its log: $build_dir/$name.log; the input: $build_dir/crashes/" >&2
    tail -n 40 "$build_dir/$name.log" >&2
    status=1
  fi
done <"$build_dir/fuzzers.txt"
[ $status -eq 0 ] && echo "fuzz: every target ran without a crash"
exit $status
