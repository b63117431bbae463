// Benchmark (not a test) of label decluttering (blocks/label_declutter.hpp): per-frame CPU time
// of LabelDeclutterer::update for 10,000 and 100,000 candidates on a 1280 x 720 screen, labels
// drifting by < 1 px per frame with jittering depths, against the same greedy without memory of
// the previous frame (reset every frame: the baseline, which flickers), measured in the same run.
//
// Usage: terralod-bench-labels [--frames N] [--seed S]
//   --frames  frames timed per size (default 200; the median and 99th percentile are reported)
//   --seed    seed of the random layout (default 1; printed)
// Labels: 40..120 x 12..18 px anywhere on the screen, priorities 0..99 (integers: many ties),
// depths 100..30000 m. Memory: about 100 bytes per candidate.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "terralod/blocks/label_declutter.hpp"
#include "timing.hpp"

namespace {

namespace tb = terralod::blocks;
namespace bench = terralod::bench;

struct Run {
  double median_ms = 0, p99_ms = 0, shown = 0, changes = 0;  // shown and changes: per frame, mean
};

Run run(const std::vector<tb::LabelCandidate>& base, const std::vector<float>& vx, int frames, unsigned seed,
        bool memory) {
  tb::LabelDeclutterer d({.screen_width = 1280, .screen_height = 720});
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> jitter(-20.0f, 20.0f);
  std::vector<tb::LabelCandidate> frame = base;
  std::vector<double> ms;
  std::vector<tb::LabelId> before, now;
  Run out;
  for (int f = 0; f < frames; ++f) {
    for (std::size_t i = 0; i < frame.size(); ++i) {  // drift < 1 px, depth jitter
      const float dx = vx[i] * float(f);
      frame[i].x0 = base[i].x0 + dx, frame[i].x1 = base[i].x1 + dx;
      frame[i].depth = base[i].depth + jitter(rng);
    }
    if (!memory) d.reset();
    const double t0 = bench::thread_cpu_ms();
    const auto shown = d.update(frame);
    ms.push_back(bench::thread_cpu_ms() - t0);
    now.assign(shown.begin(), shown.end());
    std::sort(now.begin(), now.end());
    if (f > 0) {
      std::vector<tb::LabelId> diff;
      std::set_symmetric_difference(before.begin(), before.end(), now.begin(), now.end(),
                                    std::back_inserter(diff));
      out.changes += double(diff.size()) / (frames - 1);
    }
    out.shown += double(now.size()) / frames;
    before.swap(now);
  }
  out.median_ms = bench::median(ms);
  out.p99_ms = bench::quantile(ms, 0.99);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 200;
  unsigned seed = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--frames" && i + 1 < argc) {
      frames = std::atoi(argv[++i]);
    } else if (a == "--seed" && i + 1 < argc) {
      seed = unsigned(std::strtoul(argv[++i], nullptr, 10));
    } else {
      std::fprintf(stderr, "usage: terralod-bench-labels [--frames N] [--seed S]\n");
      return 2;
    }
  }
  if (frames < 2) {
    std::fprintf(stderr, "terralod-bench-labels: --frames must be >= 2\n");
    return 2;
  }
  std::printf("label decluttering, 1280 x 720, %d frames, seed %u\n", frames, seed);
  for (const int n : {10000, 100000}) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> x(-60.0f, 1280.0f), y(-18.0f, 720.0f), w(40.0f, 120.0f),
        h(12.0f, 18.0f), depth(100.0f, 30000.0f), v(-0.9f, 0.9f);
    std::uniform_int_distribution<int> prio(0, 99);
    std::vector<tb::LabelCandidate> base;
    std::vector<float> vx;
    for (int i = 0; i < n; ++i) {
      const float x0 = x(rng), y0 = y(rng);
      base.push_back({{0, i}, x0, y0, x0 + w(rng), y0 + h(rng), double(prio(rng)), depth(rng)});
      vx.push_back(v(rng));
    }
    const Run with = run(base, vx, frames, seed, /*memory=*/true);
    const Run without = run(base, vx, frames, seed, /*memory=*/false);
    std::printf(
        "%6d candidates: update median %.3f ms, p99 %.3f ms, %.0f shown, %.1f shown-set changes/frame"
        " | without memory: median %.3f ms (ratio %.2f), %.1f changes/frame\n",
        n, with.median_ms, with.p99_ms, with.shown, with.changes, without.median_ms,
        with.median_ms / without.median_ms, without.changes);
  }
  return 0;
}
