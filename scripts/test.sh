#!/usr/bin/env bash
# Installs what is missing, builds terralod with its tests, runs them, and builds an
# out-of-tree consumer against the installed package.
# With --sanitizers, or when CI=true, it then runs the suite again under AddressSanitizer +
# UndefinedBehaviorSanitizer (build-asan/) and the multi-threaded tests under ThreadSanitizer
# (build-tsan/); about 25 more minutes on 2 cores, so a plain run skips them.
set -euo pipefail
cd "$(dirname "$0")/.."
sanitizers=0
[[ "${CI:-}" == "true" ]] && sanitizers=1
for arg in "$@"; do
  case "$arg" in
    --sanitizers) sanitizers=1 ;;
    *) echo "usage: bash scripts/test.sh [--sanitizers]" >&2; exit 2 ;;
  esac
done
# The tests the ASan pass leaves to the Release pass (their reasons are where the ASan pass is set up).
asan_exclude='RealTileFull|VrtOfTilesIsTheSameMosaic|WarpedVrtOfGeographicTiles|test_build_memory|test_cli|test_render_cli|test_texture_rules|test_texture_symbols|OpenMeshBuild.TriangleCountsAlikeTheBuilders|test_cesium_client|test_gltf_validator|KauaiVoids|test_database_build|test_build_mpi|test_bench|test_fly|test_texture_store|test_cmd_|test_bad_input_tools|TerrainRuntime.HighAndHorizon|TerrainRuntime.FastTurns|TerrainRuntime.EveryKindOfCoarse|TerrainRuntime.EveryPairOfCoarseKinds|TerrainRuntimeLoading.RandomFlights|TerrainRuntimeLoading.StandIns|TerrainRuntimeLoading.ScriptedFlight|TerrainRuntime.CurvedFlightMisses|RuntimeGeomorph.PerFrameChange|SelectiveRefinement.GuaranteeOnScriptedFlights|Timing.GeomorphGpuVsCpu|SelectiveRefinement.BoxesNeedFewerTrianglesThanSpheres|ProgressiveMesh.WithoutParallelStripsNoColumnStaysAtFullResolution|TerrainRuntime.LowFlight|TerrainRuntime.MemoryBudget|TerrainRuntime.StraightFlightMisses|TerrainRuntime.ResidentBytesCoverTheHeap|TerrainRuntime.FarBlocksHoldOnlyTheirCoarseEnd|BadInputCli|ImagePyramid.ConvertHoldsBandsOfRowsNotTheImage'
bash scripts/install-deps.sh
# Every C++ file follows .clang-format (fix with: git ls-files '*.cpp' '*.hpp' | xargs clang-format -i).
git ls-files '*.cpp' '*.hpp' | xargs clang-format --dry-run -Werror
jobs="$(nproc)"
# New build trees use Ninja (an existing tree keeps the generator it was made with): it compiles a
# library's dependants while the library is still being compiled, where Make waits for it. The
# ASan build took 466 s instead of 698 s on 2 cores.
export CMAKE_GENERATOR="${CMAKE_GENERATOR:-Ninja}"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DTERRALOD_WERROR=ON -DCMAKE_INSTALL_PREFIX="$PWD/build/install" >/dev/null
cmake --build build -j"$jobs"
if ((sanitizers)); then
  # With the sanitizer passes, each test runs once in this run: the tests the ASan pass runs
  # (the complement of asan_exclude) run there, instrumented and with the asserts on, and
  # this Release pass runs the rest. Saves about 4 CPU-minutes (2 on CI's 2 cores); a plain run
  # (the newcomer's) runs every test in Release.
  ctest --test-dir build -j"$jobs" --output-on-failure --timeout 1200 -R "$asan_exclude"
else
  ctest --test-dir build -j"$jobs" --output-on-failure --timeout 1200
fi
# The installed package must be usable by another CMake project.
cmake --install build >/dev/null
cmake -S examples/consumer -B build/consumer -DCMAKE_PREFIX_PATH="$PWD/build/install" >/dev/null
cmake --build build/consumer -j"$jobs" >/dev/null
./build/consumer/terralod-consumer

((sanitizers)) || exit 0

# ---------------------------------------------------------------------------------------------
# Sanitizer runs: ordinary configurations of the same test command (STYLE.md 12), each timed.
# -Wno-maybe-uninitialized: GCC 12 reports false positives inside libstdc++'s <regex> and
# OpenMesh's headers once -fsanitize instruments them; the normal build keeps the warning.
san_flags="-fno-omit-frame-pointer -Wno-maybe-uninitialized"
timed() {  # timed LABEL COMMAND...: runs the command, then prints how long it took
  local label="$1" t0=$SECONDS
  shift
  "$@"
  echo "test.sh: $label took $((SECONDS - t0)) s"
}

# AddressSanitizer + UndefinedBehaviorSanitizer: the whole suite except the full 1201 x 1201
# tile (RealTileFull) and the two Kauai crops (3 minutes under ASan for code paths the
# generated terrains with holes already take); the White Mountains crop keeps real data in.
# LeakSanitizer: third-party leaks are suppressed, each with its reason, in
# tests/sanitizers/lsan.supp. OpenImageIO's (a string in ImageInput::geterror on every corrupt
# PNG) is only matched with the slow unwinder, as libOpenImageIO has no frame pointers; that
# unwinder doubles the cost of every allocation (and makes llvmpipe's shader compiler
# minutes slower), so it is used for the tests that decode corrupt images only.
# Also left to the normal pass: the end-to-end tests that drive the command-line tools over
# whole pipelines (kill-and-resume builds, the MPI builds under mpirun (Open MPI's own
# allocations at MPI_Finalize would read as leaks), flights, the benchmark, texture CLI runs, and
# every tool on broken databases and camera paths): they spend minutes under ASan in code the
# unit tests above already run instrumented. Keeps the CI run shorter (40 minutes on 2 cores at most).
# Of the runtime's flights (test_terrain_runtime), the drawn-height flight, the live settings
# (changing tau mid-flight), the stalled reader, loader errors and eviction run instrumented, and
# so do the flights of test_terrain_holes, test_geomorph and test_object_drape; the low, high,
# fast-turning, memory-budget, per-kind and kind-pair flights and the flights checked frame by
# frame while blocks arrive (random, per stand-in kind, N44W072) take the same paths through the
# runtime (the low flight alone was 87 s under ASan, the memory budget 42 s); so do the straight
# and curved prefetch flights (the predictor's unit tests run instrumented), the per-frame
# geomorph change (the real-terrain geomorph flight runs) and the scripted-flight guarantee (the
# random-pose one runs), and so do the heap-against-count flight and the far blocks' partial reads
# (62 s and 49 s under ASan: the eviction flight and the tau change read and free blocks
# through the same loader, and test_block_loader's held-bytes tests run instrumented).
# The image pyramid's memory bound (ConvertHoldsBandsOfRowsNotTheImage) is measured on the
# resident set, which ASan's quarantine of freed blocks inflates; its code runs instrumented in
# the other pyramid tests.
# The GPU vs CPU geomorph timing is a measurement, meaningless under ASan;
# the draw paths it times run in the other render tests. So are the boxes-against-spheres triangle count (the guarantee tests refine
# with both bounding volumes) and the serial build of a large grid without strips (every small PM
# of the unit tests is a serial build).
# The command-line tests that run the tool many times over (test_cli, test_render_cli,
# test_texture_rules, test_texture_symbols: about 4 CPU-minutes under ASan, each terralod start instrumented) join the
# other end-to-end tests in the normal pass; the library code under them runs instrumented in the
# unit tests. So does the triangle-count comparison of the OpenMesh reference build (a
# measurement; its guarantee tests run). The two mosaics' whole-database comparisons
# (VrtOfTilesIsTheSameMosaic, WarpedVrtOfGeographicTiles: 17 s and more under ASan) build through
# the windowed and warped reads the other DemSource tests run instrumented.
# The test executables excluded whole are not built, nor are the command-line tools
# (TERRALOD_BUILD_APPS=OFF): only test_bad_input's two CLI tests (BadInputCli) ran them here, and
# compiling terralod instrumented cost about 125 CPU-s; they run in the Release pass.
asan_unbuilt='^(test_cli|test_render_cli|test_texture_rules|test_texture_symbols|test_cesium_client|test_gltf_validator|test_database_build|test_build_mpi|test_bench|test_fly.*|test_texture_store|test_cmd_.*|test_bad_input_tools)$'
asan_images='dem_reader|test_bad_input|test_fuzz_regressions'
asan() {
  # -O1 -g1: line tables are enough for reports and compile about a third faster than -O2 -g.
  # -fno-sanitize=vptr: UBSan's vptr checks need OpenImageIO's type_info (data), so with them
  # OpenImageIO and its 250 libraries are linked outright instead of loaded on first call
  # (cmake/lazy/lazy_library.cmake): 0.6 s more start-up for every test process under ASan
  # (test_dem_crs: 0.83 s against 0.24 s), about 2 of CI's 40 minutes over 540 tests. The vptr
  # check guards calls through pointers to a wrong dynamic type (terralod's own hierarchies: the
  # node strategies, DEM sources, block sources, GL contexts, thematic textures, renderers and the
  # flight demo's terrain sources); every other UBSan check stays.
  # No NDEBUG: this pass is also the one where the asserts (the misuse tier, STYLE.md 7) run.
  # The libraries are instrumented (TERRALOD_SANITIZE); the tests' own code is compiled
  # plain and linked with the runtimes: 2.5x faster to compile, and the brute-force checkers
  # inside the tests run at full speed, while every access the code under test makes is checked.
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=None -DTERRALOD_BUILD_BENCH=OFF -DTERRALOD_BUILD_APPS=OFF \
    -DTERRALOD_SANITIZE="-fsanitize=address,undefined;-fno-sanitize=vptr;-fno-sanitize-recover=undefined" \
    -DCMAKE_CXX_FLAGS="-O1 -g1 $san_flags" >/dev/null
  local targets
  # Target lists: "... test_x" (Make) or "test_x: phony" (Ninja).
  targets=$(cmake --build build-asan --target help |
    sed -n -e 's/^\.\.\. \(test_[A-Za-z0-9_]*\).*/\1/p' -e 's/^\(test_[A-Za-z0-9_]*\): .*/\1/p' | grep -Ev "$asan_unbuilt")
  # shellcheck disable=SC2086  # one target per word
  cmake --build build-asan -j"$jobs" --target $targets >/dev/null
  local asan_options="detect_leaks=1:check_initialization_order=1:detect_stack_use_after_return=1"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  export LSAN_OPTIONS="suppressions=$PWD/tests/sanitizers/lsan.supp:print_suppressions=0"
  ASAN_OPTIONS="$asan_options" \
    ctest --test-dir build-asan -j"$jobs" --output-on-failure --timeout 1200 -E "$asan_exclude|$asan_images"
  ASAN_OPTIONS="$asan_options:fast_unwind_on_malloc=0" \
    ctest --test-dir build-asan -j"$jobs" --output-on-failure --timeout 1200 -E "$asan_exclude" -R "$asan_images"
}

# ThreadSanitizer: the tests that run the PM builder's parallel strips (any hole-free grid of
# >= 257 columns and >= 65536 samples, built with 2 threads: the parallel-strip tests and the
# White Mountains and filled Kauai crops; the Kauai crop with holes builds on one thread) and
# the DEM reader (GDAL registered once per process), and the texture cache's worker threads
# (TextureCache: loads racing frames and eviction), and the CPU shading generator's row threads
# (test_topographic_texture ParallelRowsRegionsAndHoles), and the block database's reader threads
# beside a writer (test_block_database ConcurrentReadersWhileWriting), and the block loader
# thread beside the test thread (test_block_loader: loads, a stalled reader, errors, the
# database's own connection), and the runtime with its loader thread, which also prepares each
# arriving block's refinement (test_terrain_runtime's TerrainRuntimeLoading: a stalled reader,
# errors, eviction and reloads, random flights while blocks arrive; about 1.5 minutes under TSan
# on 2 cores, half of it building their database), and build_database's writer beside its
# workers and a remote builder's threads (test_remote_builder, what the MPI build runs), and
# windowed DEM reads from four threads over a pool of GDAL datasets (test_dem_source
# ConcurrentReadersGetTheSameBlocks).
# Only their executables are built. "Strip" also matches the serial build without strips
# (WithoutParallelStrips: one thread, 28 s under TSan), which is left out, and the strips of a
# grid with holes (GridsWithHolesBuildInStripsToo: 40 to 79 s under TSan), whose two strips run
# the same threads as ParallelStripsGiveAValidDeterministicPm's and are joined on one thread; it
# runs in the Release and ASan passes.
tsan_tests=(test_lazy_libraries test_progressive_mesh test_dem_reader test_dem_source test_stress_pm test_texture_cache test_topographic_texture test_block_database test_block_loader test_terrain_runtime test_remote_builder)
tsan_regex='LazyLibraries.OpenImageIOFirstCalled|RemoteBuilder|Parallel|Strip|WhiteMountainsCrop|KauaiVoidsFilledCrop|dem_reader|TextureCache|ConcurrentReaders|test_block_loader|TerrainRuntimeLoading.(Stalled|LoaderErrors|Evicted|RandomFlights)'
tsan() {
  # -O1 -g1 as for ASan: line tables for the reports, a faster compile than -O2 -g.
  cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=None -DTERRALOD_BUILD_BENCH=OFF \
    -DTERRALOD_BUILD_APPS=OFF -DCMAKE_CXX_FLAGS="-O1 -g1 -DNDEBUG -fsanitize=thread $san_flags" >/dev/null
  cmake --build build-tsan -j"$jobs" --target "${tsan_tests[@]}" >/dev/null
  TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/tests/sanitizers/tsan.supp" \
    ctest --test-dir build-tsan -j"$jobs" --output-on-failure --timeout 1200 -R "$tsan_regex" -E 'RealTileFull|WithoutParallelStrips|GridsWithHolesBuildInStripsToo'
}

timed "ASan+UBSan build and test" asan
timed "TSan build and test" tsan
