// terralod bench: the run-time-versus-error benchmark of LOD strategies (bench/lod_benchmark.hpp),
// writing bench.csv, the two plots and summary.md.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "lod_benchmark.hpp"

namespace terralod::cli {
namespace {

namespace fs = std::filesystem;

std::vector<double> parse_taus(const std::string& text) {
  std::vector<double> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size() || !std::isfinite(v) || v <= 0)
      throw UsageError("option '--taus' wants positive numbers separated by commas, not '" + text + "'");
    out.push_back(v);
  }
  if (out.empty()) throw UsageError("option '--taus' is empty");
  return out;
}

}  // namespace

CommandSpec bench_spec() {
  CommandSpec s;
  s.name = "bench";
  s.summary =
      "Run-time-versus-error benchmark of PM blocks against chunked LOD, TIN, non-regular grid, full grid.";
  s.description =
      "Flies two fixed scripted flights (a low terrain-following circle and a high diagonal pass)\n"
      "over N44W072.hgt from --data (or, with --short or when that file is absent, over a\n"
      "generated terrain) and, for every tau and every strategy selected for the same guarantee\n"
      "(screen-space error <= tau), measures triangles drawn, LOD update time, OSMesa draw time,\n"
      "frame time (median, p99), the worst screen-space error found by an independent brute-force\n"
      "checker and the popping (largest per-frame change of the surface, pixels).\n"
      "Writes to --out: bench.csv (one row per strategy x tau), error_vs_time.png,\n"
      "error_vs_triangles.png and summary.md (ratios to chunked LOD, PASS/FAIL per target).\n"
      "Progress goes to stderr, one line per stage. Exit status 0 when the run completed (the\n"
      "targets' PASS/FAIL is in summary.md and on stdout).";
  s.options = {
      {"--data", "DIR", "folder with N44W072.hgt (default: the build's TERRALOD_DATA_DIR)"},
      {"--out", "DIR", "output folder, created if needed (default: terralod-bench)"},
      {"--short", "", "a quick run on a generated 129 x 129 terrain (40 frames)"},
      {"--frames", "N", "frames in all over the two flights (default 600; --short 40), >= 2"},
      {"--size", "WxH", "viewport in pixels (default 1280x720)"},
      {"--taus", "LIST", "tolerances in pixels, comma-separated (default 0.5,1,2,4,8)"},
      {"--dem", "FILE", "fly over this DEM instead of N44W072 (e.g. from 'terralod generate --size 4097')"},
      {"--strategies", "LIST",
       "comma-separated subset of pm_blocks,chunked_lod,tin,nonregular,full_grid (default all)"}};
  return s;
}

int cmd_bench(const Args& a) {
  bench::LodBenchmarkOptions o =
      a.has("--short") ? bench::short_benchmark_options() : bench::LodBenchmarkOptions{};
  o.frames = int(a.get_int("--frames", o.frames, 2, 1000000));
  const auto [w, h] = a.get_size("--size", {o.width_px, o.height_px}, 16, 16384);
  o.width_px = int(w), o.height_px = int(h);
  if (a.has("--taus")) o.taus = parse_taus(a.get("--taus"));
  const std::string dem = (fs::path(a.get("--data", bench::default_data_dir())) / "N44W072.hgt").string();
  if (a.has("--strategies")) {
    std::stringstream in(a.get("--strategies"));
    for (std::string item; std::getline(in, item, ',');) o.strategies.push_back(item);
  }
  if (a.has("--dem")) {
    o.dem_path = a.get("--dem");
  } else if (!a.has("--short")) {
    if (fs::exists(dem))
      o.dem_path = dem;
    else
      std::fprintf(stderr, "bench: %s is absent: flying over a generated terrain instead\n", dem.c_str());
  }
  const fs::path out = a.get("--out", "terralod-bench");
  fs::create_directories(out);
  o.log = [](const std::string& line) {
    std::fprintf(stderr, "bench: %s\n", line.c_str());
    std::fflush(stderr);
  };
  const bench::LodBenchmarkResult r = bench::run_lod_benchmark(o);
  bench::write_csv(r, (out / "bench.csv").string());
  bench::write_plots(r, out.string());
  const std::string md = bench::summary_markdown(r);
  {
    const fs::path p = out / "summary.md";
    std::ofstream f(p, std::ios::binary);
    f << md;
    if (!f.flush()) throw std::runtime_error(p.string() + ": cannot write the summary");
  }
  std::fprintf(stderr, "bench: wrote %s/{bench.csv, error_vs_time.png, error_vs_triangles.png, summary.md}\n",
               out.string().c_str());
  for (const bench::TargetCheck& c : bench::check_targets(r))
    std::printf("%s: %s — %s\n", c.pass ? "PASS" : "FAIL", c.name.c_str(), c.detail.c_str());
  return 0;
}

}  // namespace terralod::cli
