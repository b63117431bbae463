// End-to-end test of `terralod bench --short`: runs the built binary on its generated terrain
// and checks the CSV (every column of every strategy x tau filled, the guarantee measured by the
// independent checker held, hand-derived counts), the two PNG plots and the summary.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "run_command.hpp"

namespace {

namespace fs = std::filesystem;

using CliResult = terralod::test::CommandResult;
using terralod::test::slurp;

/// A folder of this process's own, removed when the process ends (tests/support/run_command.hpp).
const fs::path& tmp_dir() { return terralod::test::process_temp_dir("bench"); }

CliResult terralod(const std::string& args) { return terralod::test::run_tool(TERRALOD_CLI, args); }

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, sep)) out.push_back(item);
  if (!s.empty() && s.back() == sep) out.push_back("");
  return out;
}

// The short run: 129 x 129 generated samples, 40 frames, tau = 0.5, 1, 2, 4, 8 px, 640 x 360.
TEST(Bench, ShortRunWritesCompleteCsvPlotsAndSummary) {
  const fs::path out = tmp_dir() / "short";
  const auto t0 = std::chrono::steady_clock::now();
  // A smaller viewport than the default 1280 x 720 keeps the OSMesa draws short.
  const CliResult r = terralod("bench --short --size 640x360 --out '" + out.string() + "'");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(r.status, 0) << r.err;
  std::printf("terralod bench --short: %.1f s\n%s", seconds, r.out.c_str());
  // Progress: one line per stage on stderr.
  EXPECT_NE(r.err.find("bench: build pm_blocks"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("bench: run chunked_lod tau 1 px"), std::string::npos) << r.err;

  // CSV: a header and 5 strategies x 5 taus rows, every column filled with a finite number.
  const std::vector<std::string> lines = split(slurp(out / "bench.csv"), '\n');
  ASSERT_GE(lines.size(), 2u);
  const std::vector<std::string> header = split(lines[0], ',');
  ASSERT_EQ(header.size(), 23u) << lines[0];
  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
  for (const char* name :
       {"strategy", "tau_px", "frames", "drawn_frames", "checked_frames", "triangles_median",
        "update_median_ms", "update_p99_ms", "update_cpu_median_ms", "draw_median_ms", "frame_median_ms",
        "frame_p99_ms", "measured_worst_px", "guaranteed_px", "popping_px"})
    ASSERT_TRUE(col.count(name)) << name;
  std::map<std::string, std::map<double, std::vector<double>>> rows;  // strategy -> tau -> values
  std::size_t n = 0;
  for (std::size_t l = 1; l < lines.size(); ++l) {
    if (lines[l].empty()) continue;
    ++n;
    const std::vector<std::string> f = split(lines[l], ',');
    ASSERT_EQ(f.size(), header.size()) << lines[l];
    std::vector<double> v(f.size(), 0.0);
    for (std::size_t i = 1; i < f.size(); ++i) {
      ASSERT_FALSE(f[i].empty()) << header[i] << " empty in " << lines[l];
      std::size_t used = 0;
      v[i] = std::stod(f[i], &used);
      ASSERT_EQ(used, f[i].size()) << header[i] << " in " << lines[l];
      ASSERT_TRUE(std::isfinite(v[i]) && v[i] >= 0) << header[i] << " in " << lines[l];
    }
    rows[f[0]][v[col["tau_px"]]] = v;
  }
  EXPECT_EQ(n, 25u);
  const std::set<std::string> strategies = {"pm_blocks", "chunked_lod", "tin", "nonregular", "full_grid"};
  ASSERT_EQ(rows.size(), strategies.size());
  for (const auto& [name, by_tau] : rows) {
    EXPECT_TRUE(strategies.count(name)) << name;
    ASSERT_EQ(by_tau.size(), 5u) << name;
    for (const auto& [tau, v] : by_tau) {
      SCOPED_TRACE(name + " tau " + std::to_string(tau));
      EXPECT_EQ(v[col["frames"]], 40.0);  // 20 + 20 frames of the two flights
      EXPECT_GT(v[col["drawn_frames"]], 0.0);
      EXPECT_EQ(v[col["checked_frames"]], 8.0);  // frames 4, 9, 14, 19 of each flight
      EXPECT_GT(v[col["triangles_median"]], 0.0);
      EXPECT_GT(v[col["draw_median_ms"]], 0.0);
      EXPECT_GE(v[col["frame_median_ms"]], v[col["draw_median_ms"]]);
      // The guarantee, as the selection reports it and as the independent checker measures it.
      EXPECT_LE(v[col["guaranteed_px"]], tau * (1 + 1e-9));
      EXPECT_LE(v[col["measured_worst_px"]], tau);
    }
  }
  // The full grid: 128 x 128 cells, two triangles each, no error, nothing changes between frames.
  for (const auto& [tau, v] : rows["full_grid"]) {
    EXPECT_EQ(v[col["triangles_median"]], 2.0 * 128 * 128);
    EXPECT_EQ(v[col["measured_worst_px"]], 0.0);
    EXPECT_EQ(v[col["popping_px"]], 0.0);
    EXPECT_EQ(v[col["update_median_ms"]], 0.0);
    EXPECT_EQ(v[col["changed_frames"]], 0.0);
  }
  // The LOD strategies follow tau (far more triangles at 0.5 px than at 8 px; not compared
  // tau by tau: culling can make a finer selection smaller), draw fewer than the full grid at
  // 8 px, and their surfaces change from frame to frame.
  for (const char* s : {"pm_blocks", "chunked_lod", "tin", "nonregular"})
    EXPECT_GT(rows[s][0.5][col["triangles_median"]], 1.5 * rows[s][8.0][col["triangles_median"]]) << s;
  EXPECT_LT(rows["pm_blocks"][8.0][col["triangles_median"]], 2.0 * 128 * 128);
  // The runtime's frames wait for what the previous frame queued: nothing needed is missing,
  // and it reports its resident memory.
  for (const auto& [tau, v] : rows["pm_blocks"]) {
    EXPECT_EQ(v[col["missing_frames"]], 0.0) << tau;
    EXPECT_GT(v[col["peak_resident_bytes"]], 0.0) << tau;
  }
  EXPECT_GT(rows["pm_blocks"][8.0][col["popping_px"]], 0.0);

  // Plots: valid PNGs, 960 x 640 RGB, not blank.
  for (const char* png : {"error_vs_time.png", "error_vs_triangles.png"}) {
    SCOPED_TRACE(png);
    auto in = OIIO::ImageInput::open((out / png).string());
    ASSERT_TRUE(in) << OIIO::geterror();
    EXPECT_EQ(std::string(in->format_name()), "png");
    const OIIO::ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.width, 960);
    EXPECT_EQ(spec.height, 640);
    ASSERT_EQ(spec.nchannels, 3);
    std::vector<unsigned char> px(std::size_t(spec.width) * spec.height * 3);
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px.data()));
    std::size_t coloured = 0;  // pixels of the series (saturated colours, not grey or white)
    for (std::size_t i = 0; i < px.size(); i += 3) {
      const int mx = std::max({px[i], px[i + 1], px[i + 2]}), mn = std::min({px[i], px[i + 1], px[i + 2]});
      coloured += mx - mn > 60;
    }
    EXPECT_GT(coloured, 500u);
  }

  // Summary: the table with every strategy at tau = 1 and the five target lines.
  const std::string md = slurp(out / "summary.md");
  for (const std::string& s : strategies)
    EXPECT_NE(md.find("| 1 | " + s + " |"), std::string::npos) << s << "\n" << md;
  std::size_t targets = 0;
  for (const std::string& l : split(md, '\n'))
    targets += l.rfind("- PASS: ", 0) == 0 || l.rfind("- FAIL: ", 0) == 0;
  EXPECT_EQ(targets, 5u) << md;
  EXPECT_NE(md.find("PASS: measured worst screen error <= tau"), std::string::npos) << md;
  EXPECT_NE(md.find("PASS: PM blocks: every frame complete"), std::string::npos) << md;
}

TEST(Bench, StrategiesSubsetAndBadNames) {
  const fs::path out = tmp_dir() / "subset";
  const CliResult r =
      terralod("bench --short --size 320x180 --frames 8 --taus 1 --strategies pm_blocks,chunked_lod --out '" +
               out.string() + "'");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::vector<std::string> lines = split(slurp(out / "bench.csv"), '\n');
  std::set<std::string> seen;
  for (std::size_t l = 1; l < lines.size(); ++l)
    if (!lines[l].empty()) seen.insert(split(lines[l], ',')[0]);
  EXPECT_EQ(seen, (std::set<std::string>{"pm_blocks", "chunked_lod"}));
  const CliResult bad =
      terralod("bench --short --strategies pm_blocks,nosuch --out '" + (tmp_dir() / "bad2").string() + "'");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find("nosuch"), std::string::npos) << bad.err;
}

TEST(Bench, BadOptionsAreUsageErrors) {
  CliResult r = terralod("bench --short --taus 1,0 --out '" + (tmp_dir() / "bad").string() + "'");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("--taus"), std::string::npos) << r.err;
  r = terralod("bench --short --size 10x10");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("--size"), std::string::npos) << r.err;
  r = terralod("bench --help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("--short"), std::string::npos) << r.out;
}

}  // namespace
