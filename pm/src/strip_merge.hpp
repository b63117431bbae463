// Private to the PM builder (pm_builder.cpp): the collapse sequences of the parallel strips
// merged into one.
//
// Collapses of different strips are independent (their 1-rings never cross a cut column), so
// any interleaving of the strips' sequences is a valid sequence. A strip that went further than
// the others would put its higher-error collapses before the others' lower-error ones: every
// strip's sequence is kept only up to the smallest of their final prefix maxima (the common
// error), the rest is left to the joined mesh, and the kept prefixes are merged in error order
// (stable within a strip). Memory: none beyond the output.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#include "terralod/pm/progressive_mesh.hpp"

namespace terralod::pm::detail {
namespace {  // one translation unit (pm_builder.cpp)

/// Appends the merged prefixes of the strips' sequences `seq` to `out`.
inline void merge_strips(const std::vector<std::vector<Collapse>>& seq, std::vector<Collapse>& out) {
  const std::size_t n = seq.size();
  double common = 1e300;
  for (const auto& q : seq) {
    double m = 0;
    for (const auto& c : q) m = std::max(m, c.error);
    common = std::min(common, m);
  }
  std::vector<std::size_t> keep(n), at(n, 0);
  for (std::size_t t = 0; t < n; ++t) {
    std::size_t k = 0;
    while (k < seq[t].size() && seq[t][k].error <= common) ++k;
    keep[t] = k;
  }
  for (;;) {  // k-way merge by error
    std::size_t pick = n;
    for (std::size_t t = 0; t < n; ++t)
      if (at[t] < keep[t] && (pick == n || seq[t][at[t]].error < seq[pick][at[pick]].error)) pick = t;
    if (pick == n) break;
    out.push_back(seq[pick][at[pick]++]);
  }
}

}  // namespace
}  // namespace terralod::pm::detail
