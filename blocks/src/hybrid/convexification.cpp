// The cavity decoder of Fig. 7 and the corner tessellation of section 2.1 of Boo, Amor and
// Doellner's hybrid grid + TIN paper (see convexification.hpp for the contracts).
// Memory: O(sequence length) for the decoder (a stack of open cavities and a position hash),
// O(hull + corners) for the corner tessellation.
#include "terralod/blocks/hybrid/convexification.hpp"

#include <algorithm>
#include <cassert>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace terralod::blocks::hybrid {

namespace {

constexpr std::size_t kBeyond = std::numeric_limits<std::size_t>::max();

struct Frame {
  std::size_t apex;  // position in the sequence of the cavity's starting vertex
  std::size_t last;  // position of the most recent fan vertex, kBeyond = none yet
  std::size_t end;   // position of the closing vertex, kBeyond = outside the cell
};

}  // namespace

CavityDecode decode_cavities(std::span<const std::uint32_t> seq, std::span<const std::uint32_t> conn,
                             bool trace, std::span<const std::size_t> gaps) {
  CavityDecode out;
  const std::size_t n = conn.size();
  std::unordered_map<std::uint32_t, std::size_t> pos;
  pos.reserve(seq.size() * 2);
  for (std::size_t p = 0; p < seq.size(); ++p) {
    assert(seq[p] < n);
    pos.emplace(seq[p], p);
  }
  std::vector<Frame> stack;
  std::size_t closable = 0;  // frames on the stack whose end lies inside the sequence
  auto emit = [&](Frame& f, std::size_t p, DecodeStep* step) {
    if (f.last != kBeyond) {
      FanTriangle t{seq[f.apex], seq[f.last], seq[p]};
      out.triangles.push_back(t);
      if (step) {
        step->has_triangle = true;
        step->triangle = t;
      }
    }
    f.last = p;
  };
  auto s_list = [&] {
    std::vector<std::uint32_t> s;
    for (const Frame& f : stack) s.push_back(seq[f.apex]);
    return s;
  };
  for (std::size_t p = 0; p < seq.size(); ++p) {
    const std::uint32_t v = seq[p];
    DecodeStep step;
    step.vertex = v;
    // Lines 7-13: v extends the fan of the innermost open cavity.
    if (!stack.empty()) emit(stack.back(), p, trace ? &step : nullptr);
    // Lines 14-26: v closes cavities; each closing adds the parent's external triangle.
    while (!stack.empty() && stack.back().end == p) {
      if (trace) {
        step.s_list = s_list();
        step.starting_vertex = seq[stack.back().apex];
        out.steps.push_back(step);
        step = DecodeStep{};
        step.vertex = v;
      }
      stack.pop_back();
      --closable;
      if (!stack.empty()) emit(stack.back(), p, trace ? &step : nullptr);
    }
    // Lines 30-38: v opens a cavity when its connectivity is larger than one.
    const std::uint32_t c = std::binary_search(gaps.begin(), gaps.end(), p) ? 1 : conn[v];
    bool opens = false, opens_beyond = false;
    std::size_t end = kBeyond;
    if (c > 1) {
      const std::uint32_t target = std::uint32_t((std::uint64_t(v) + c) % n);
      auto it = pos.find(target);
      opens = true;
      if (it != pos.end() && it->second > p)
        end = it->second;
      else
        opens_beyond = true;
    }
    // Lines 4-5 and 27-28: the convex hull.
    const bool hull = stack.empty() || (closable == 0 && (opens_beyond || p + 1 == seq.size()));
    if (hull) out.hull.push_back(v);
    if (opens) {
      stack.push_back(Frame{p, kBeyond, end});
      if (end != kBeyond) ++closable;
    }
    if (trace) {
      step.starting_vertex = stack.empty() ? -1 : std::int64_t(seq[stack.back().apex]);
      step.s_list = s_list();
      out.steps.push_back(step);
    }
  }
  return out;
}

std::vector<std::array<std::uint32_t, 3>> corner_tessellation(std::span<const PlanPoint> hull,
                                                              std::span<const PlanPoint> corners) {
  std::vector<std::array<std::uint32_t, 3>> tris;
  if (hull.empty()) return tris;
  const std::uint32_t m = std::uint32_t(hull.size() - 1), base = std::uint32_t(hull.size());
  // orient2d(a, b, c) > 0: c left of a->b. Lattice coordinates make this exact in double.
  auto orient = [](const PlanPoint& a, const PlanPoint& b, const PlanPoint& c) {
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
  };
  std::uint32_t i = 0, k = 0;
  const std::uint32_t nc = std::uint32_t(corners.size());
  if (nc == 0) {
    if (m > 0 && hull.size() > 2)
      throw std::runtime_error("corner tessellation: a hull chain of " + std::to_string(hull.size()) +
                               " vertices with no uncovered corner");
    return tris;
  }
  while (i < m || k + 1 < nc) {
    // The cross-product test: corner k sees hull edge (i, i+1) when it is strictly on its right.
    if (i < m && orient(hull[i], hull[i + 1], corners[k]) < 0) {
      tris.push_back({base + k, i + 1, i});
      ++i;
    } else if (k + 1 < nc) {
      tris.push_back({i, base + k, base + k + 1});  // corner shift
      ++k;
    } else {
      throw std::runtime_error("corner tessellation: hull edge " + std::to_string(i) +
                               " is seen by no remaining corner (the chain is not convex)");
    }
  }
  return tris;
}

}  // namespace terralod::blocks::hybrid
