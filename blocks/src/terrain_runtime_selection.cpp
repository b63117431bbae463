// Step 2 of the terrain runtime's frame (terrain_runtime.hpp): the selection over the
// approximation tree (culling, coarse nodes within tau / 2, PM blocks as their stand-ins or
// refined, ancestors drawn for missing blocks), and the same rules run ahead for prefetching.
#include <limits>

#include "terrain_runtime_internal.hpp"
#include "terralod/blocks/terrain_runtime.hpp"

namespace terralod::blocks {

using detail::kSelectShare;

namespace {
// The coarsest error a PM block's leaves may have for the view to meet `limit` over its box:
// View::vertical_error_px is linear in the error.
double floor_for(const pm::View& view, const pm::Box& box, double limit) {
  const double px_per_m = view.vertical_error_px(box, 1.0);
  return px_per_m > 0 ? limit / px_per_m : std::numeric_limits<double>::infinity();
}
}  // namespace

bool TerrainRuntime::covers(const Block& b, double floor_m) const {
  return b.data->dag->floor_error() <= floor_m;
}

// Selection (header, step 2). Returns false when the subtree needs a block that is not resident.
bool TerrainRuntime::visit(const pm::View& view, double tau, std::int64_t id, Selection& sel,
                           double parent_px) {
  const TreeNode& n = tree_.node(id);
  ++stats_.nodes_visited;
  if (view.outside(n.bbox)) {
    ++stats_.nodes_culled;
    return true;
  }
  const double limit = kSelectShare * tau;
  if (n.strategy == Strategy::PmBlock) {
    // The stand-in, when it meets tau / 2: the whole box first, then triangle by triangle.
    // The box test needs the summary's fields only; the stand-in is read for the finer one.
    const std::size_t i = grid_.index(*n.block);
    if (sums_->has_standin(i) &&
        (view.vertical_error_px(n.bbox, sums_->fields()[i].standin_error) <= limit ||
         standin_bound_px(grid_, *n.block, sums_->summary(i, frame_), view) <= limit)) {
      sel.standins.push_back(id);
      return true;
    }
    // A resident block is drawn even when its leaves are coarser than this view needs (a finer
    // copy is on its way): it is closer to the terrain than an ancestor, and its bound says so.
    sel.needed.push_back({id, parent_px, floor_for(view, n.bbox, limit)});
    if (!blocks_.count(*n.block)) return false;
    sel.pms.push_back(id);
    return true;
  }
  const double b = view.vertical_error_px(n.bbox, n.error);
  if (n.leaf() || b <= limit) {
    sel.coarse.push_back(id);
    return true;
  }
  const std::size_t c0 = sel.coarse.size(), p0 = sel.pms.size(), s0 = sel.standins.size();
  bool complete = true;
  for (std::int64_t c : n.children) complete = visit(view, tau, c, sel, b) && complete;
  if (!complete) {  // a needed block is missing: this node, resident, is drawn for its subtree
    sel.coarse.resize(c0);
    sel.pms.resize(p0);
    sel.standins.resize(s0);
    sel.coarse.push_back(id);
    ++stats_.fallback_nodes;
  }
  return true;
}

// The PM blocks a view would need (the selection's rules, with the stand-in tried by its whole
// box only: a cheap, conservative test for prefetching), largest screen error first.
void TerrainRuntime::needed_at(const pm::View& view, double tau, std::int64_t id, double parent_px,
                               std::vector<Want>& out) const {
  const TreeNode& n = tree_.node(id);
  if (view.outside(n.bbox)) return;
  const double limit = kSelectShare * tau;
  if (n.strategy == Strategy::PmBlock) {
    const std::size_t i = grid_.index(*n.block);
    if (sums_->has_standin(i) && view.vertical_error_px(n.bbox, sums_->fields()[i].standin_error) <= limit)
      return;
    out.push_back({-parent_px, *n.block, floor_for(view, n.bbox, limit)});
    return;
  }
  const double b = view.vertical_error_px(n.bbox, n.error);
  if (n.leaf() || b <= limit) return;
  for (std::int64_t c : n.children) needed_at(view, tau, c, b, out);
}

}  // namespace terralod::blocks
