// SelectiveRefinement's output: the logical active mesh and the displayed (geomorphing) mesh,
// as indexed triangle lists.
#include <algorithm>
#include <array>
#include <cstdint>
#include <numeric>
#include <vector>

#include "terralod/pm/selective_refinement.hpp"

namespace terralod::pm {

namespace {
constexpr std::uint32_t kNone = CollapseDag::kNone;

// Triangles given by corner(i) -> the three samples of triangle i (i < n) as vertices numbered in
// order of first use (samples) and triangles indexing them; `index` (per sample, all kNone on
// entry) is left as it was found.
template <class Corners>
void index_corners(std::size_t n, const Corners& corner, std::vector<std::uint32_t>& index,
                   std::vector<std::uint32_t>& samples,
                   std::vector<std::array<std::uint32_t, 3>>& triangles) {
  samples.clear();
  triangles.clear();
  triangles.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t* c = corner(i);
    std::array<std::uint32_t, 3> t;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t s = c[k];
      if (index[s] == CollapseDag::kNone) {
        index[s] = std::uint32_t(samples.size());
        samples.push_back(s);
      }
      t[k] = index[s];
    }
    triangles.push_back(t);
  }
  for (std::uint32_t s : samples) index[s] = CollapseDag::kNone;
}
}  // namespace

void SelectiveRefinement::index_faces(const std::vector<std::uint32_t>& faces,
                                      std::vector<std::uint32_t>& samples,
                                      std::vector<std::array<std::uint32_t, 3>>& triangles) const {
  index_corners(
      faces.size(), [&](std::size_t i) { return dag_->face(faces[i]).data(); }, scratch_index_, samples,
      triangles);
}

TriangleMesh SelectiveRefinement::mesh() const {
  std::vector<std::uint32_t> faces = active_;
  std::sort(faces.begin(), faces.end());
  TriangleMesh m;
  index_faces(faces, m.vertices, m.triangles);
  for (std::uint32_t f : faces) m.error_bound = std::max(m.error_bound, dag_->face_saturated_error(f));
  return m;
}

// The displayed mesh into `out` (its storage reused), the active faces read from face_rec_
// (parallel to active_: corners and error side by side, one pass over contiguous records), in
// the order `order` gives as positions in active_ (null: active_'s own order).
void SelectiveRefinement::render_into(const std::vector<std::uint32_t>* order, RenderMesh& out) const {
  const std::size_t n = face_rec_.size();
  auto at = [&](std::size_t i) -> const FaceRec& { return face_rec_[order ? (*order)[i] : i]; };
  index_corners(
      n, [&](std::size_t i) { return at(i).s; }, scratch_index_, out.samples, out.triangles);
  out.positions.clear();
  out.positions.reserve(out.samples.size());
  for (std::uint32_t s : out.samples) {
    const std::array<double, 3> p = displayed(s);
    out.positions.push_back(dag_->position(p[0], p[1], p[2]));
  }
  out.errors.resize(n);
  for (std::size_t i = 0; i < n; ++i) out.errors[i] = at(i).error;
}

void SelectiveRefinement::render_mesh_into(RenderMesh& out) const { render_into(nullptr, out); }

RenderMesh SelectiveRefinement::render_mesh() const {
  std::vector<std::uint32_t> order(active_.size());  // ordered by face id, like mesh()
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(),
            [&](std::uint32_t a, std::uint32_t b) { return active_[a] < active_[b]; });
  RenderMesh r;
  render_into(&order, r);
  return r;
}

}  // namespace terralod::pm
