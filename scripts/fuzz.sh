#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) and runs each for a given time.
#
# Usage: bash scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]     (default 60 s, every target)
#
# Corpora grow in fuzz/corpus/<target>/ (seeded with small valid inputs each run; not committed),
# and fuzz/regressions/<target>/ is read as extra seeds. A crash, sanitizer report, timeout
# (10 s per input; 30 s for fuzz_dem_reader, see below) or out-of-memory (2 GiB) stops that
# target and leaves the input in fuzz/artifacts/<target>/; keep it under fuzz/regressions/<target>/ once fixed, where
# tests/stress/test_fuzz_regressions.cpp replays it in every test run.
# Prints one line per target; exits 1 if any target found something.
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-60}"
shift || true
targets=("$@")
((${#targets[@]})) || targets=(fuzz_pm_decoder fuzz_dem_reader fuzz_camera_path fuzz_block_database fuzz_tree_decoder fuzz_block_summaries fuzz_mesh_reader fuzz_json fuzz_object_rules)
[[ "$secs" =~ ^[0-9]+$ ]] || { echo "fuzz.sh: SECONDS_PER_TARGET must be a whole number, not '$secs'" >&2; exit 2; }

# Debian 12: clang 14 is the default clang; libFuzzer's runtime is in libclang-rt-14-dev.
bash scripts/install-deps.sh clang libclang-rt-14-dev

build="${TERRALOD_FUZZ_BUILD:-build-fuzz}"  # several runs at once need separate folders
jobs="$(nproc)"
flags="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
cmake -S . -B "$build" -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" -DTERRALOD_BUILD_FUZZERS=ON \
  -DTERRALOD_BUILD_TESTS=OFF -DTERRALOD_BUILD_APPS=OFF -DTERRALOD_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j"$jobs" --target terralod_fuzz_seeds "${targets[@]}" >/dev/null

export ASAN_OPTIONS="${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$PWD/tests/sanitizers/lsan.supp:print_suppressions=0}"
"$build/fuzz/terralod_fuzz_seeds" fuzz/corpus

status=0
for t in "${targets[@]}"; do
  corpus="fuzz/corpus/$t" artifacts="fuzz/artifacts/$t/" log="$build/$t.log"
  mkdir -p "$corpus" "$artifacts" "fuzz/regressions/$t"
  before=$(find "$artifacts" -type f | wc -l)
  set +e
  # The DEM readers fill voids iteratively on rasters of up to 2^20 samples: an all-void
  # 5 x 65284 GeoTIFF takes 0.3 s in Release but 4 s of CPU under the fuzzer's coverage
  # instrumentation (10 s wall on a loaded machine); it is in fuzz/regressions as a guard.
  timeout=10
  [[ "$t" == fuzz_dem_reader ]] && timeout=30
  "$build/fuzz/$t" -max_total_time="$secs" -timeout="$timeout" -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$artifacts" "$corpus" "fuzz/regressions/$t" >"$log" 2>&1
  rc=$?
  set -e
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo "?")
  size=$(find "$corpus" -type f | wc -l)
  new=$(find "$artifacts" -type f | wc -l)
  if ((rc == 0 && new == before)); then
    echo "$t: ok, $runs runs in $secs s, coverage $cov edges, corpus $size inputs"
  else
    status=1
    artifact=$(ls -t "$artifacts" 2>/dev/null | head -1)
    echo "$t: FOUND ($(grep -m1 -oE 'ERROR: [A-Za-z]+: [a-z-]+|fuzz_[a-z_]+: .*|runtime error: .*|deadly signal|timeout|out-of-memory' "$log" | head -1)) -> $artifacts$artifact, log $log"
  fi
done
exit "$status"
