// ProgressiveMesh: validation of its parts, and uniform extraction at a given L-infinity error.
#include "terralod/pm/progressive_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace terralod::pm {

double ProgressiveMesh::error_quantum_for(const Heightfield& hf) {
  double lo = 1e300, hi = -1e300;
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) lo = std::min(lo, hf[i]), hi = std::max(hi, hf[i]);
  const double range = std::max(hi > lo ? hi - lo : 0.0, 1e-9);
  return std::ldexp(1.0, int(std::ceil(std::log2(range / 16777216.0))));
}

bool ProgressiveMesh::full_face(std::uint32_t f, std::array<std::uint32_t, 3>& out) const {
  const std::uint32_t W = std::uint32_t(hf_.width());
  const std::uint32_t cell = f / 2, i = cell % (W - 1), j = cell / (W - 1);
  const std::uint32_t v00 = j * W + i, v10 = v00 + 1, v01 = v00 + W, v11 = v01 + 1;
  if (f % 2 == 0)
    out = {v00, v10, v11};
  else
    out = {v00, v11, v01};
  if (hf_.has_holes() && !(hf_.valid(out[0]) && hf_.valid(out[1]) && hf_.valid(out[2]))) return false;
  if (!dropped_faces_.empty() && std::binary_search(dropped_faces_.begin(), dropped_faces_.end(), f))
    return false;
  return true;
}

ProgressiveMesh ProgressiveMesh::from_parts(Heightfield hf, ErrorMetric metric, double error_quantum,
                                            std::vector<Collapse> collapses,
                                            std::vector<std::uint32_t> dropped) {
  ProgressiveMesh pm;
  pm.hf_ = std::move(hf);
  pm.metric_ = metric;
  pm.error_quantum_ = error_quantum;
  pm.collapses_ = std::move(collapses);
  pm.dropped_faces_ = std::move(dropped);
  pm.finish();
  return pm;
}

void ProgressiveMesh::finish() {
  const int W = hf_.width(), H = hf_.height();
  if (W < 2 || H < 2)
    throw std::invalid_argument("progressive mesh: grid is " + std::to_string(W) + " x " + std::to_string(H) +
                                "; at least 2 x 2 samples are needed");
  if (!(error_quantum_ > 0.0) || !std::isfinite(error_quantum_))
    throw std::invalid_argument("progressive mesh: error quantum must be a positive number");
  if (!std::is_sorted(dropped_faces_.begin(), dropped_faces_.end()) ||
      (!dropped_faces_.empty() && dropped_faces_.back() >= full_face_slots()))
    throw std::invalid_argument("progressive mesh: dropped face list is unsorted or out of range");
  present_.assign(hf_.size(), 0);
  std::array<std::uint32_t, 3> t;
  for (std::uint32_t f = 0; f < full_face_slots(); ++f)
    if (full_face(f, t)) present_[t[0]] = present_[t[1]] = present_[t[2]] = 1;
  full_vertex_count_ = std::size_t(std::count(present_.begin(), present_.end(), 1));
  // Every collapse removes a live vertex onto another live vertex.
  std::vector<std::uint8_t> alive = present_;
  prefix_max_.assign(collapses_.size() + 1, 0.0);
  for (std::size_t k = 0; k < collapses_.size(); ++k) {
    const Collapse& c = collapses_[k];
    if (c.u >= hf_.size() || c.w >= hf_.size() || c.u == c.w || !alive[c.u] || !alive[c.w])
      throw std::invalid_argument("progressive mesh: collapse " + std::to_string(k) + " (" +
                                  std::to_string(c.u) + " -> " + std::to_string(c.w) +
                                  ") does not join two live vertices");
    if (!(c.error >= 0.0) || !std::isfinite(c.error))
      throw std::invalid_argument("progressive mesh: collapse " + std::to_string(k) +
                                  " has an invalid error");
    alive[c.u] = 0;
    prefix_max_[k + 1] = std::max(prefix_max_[k], c.error);
  }
}

std::size_t ProgressiveMesh::collapses_within(double max_error) const {
  // prefix_max_ is non-decreasing: the answer is the last k with prefix_max_[k] <= max_error.
  auto it = std::upper_bound(prefix_max_.begin(), prefix_max_.end(), max_error);
  return std::size_t(it - prefix_max_.begin()) - 1;
}

TriangleMesh ProgressiveMesh::extract(double max_error) const {
  if (!(max_error >= 0.0)) throw std::invalid_argument("extract: max_error must be >= 0");
  return extract_after(collapses_within(max_error));
}

TriangleMesh ProgressiveMesh::extract_after(std::size_t count) const {
  if (count > collapses_.size())
    throw std::invalid_argument("extract_after: count exceeds the number of collapses");
  // Representative of every sample after `count` collapses; see the header for why the mesh
  // is exactly the image of the full-resolution faces under this map.
  std::vector<std::uint32_t> rep(hf_.size());
  for (std::uint32_t i = 0; i < rep.size(); ++i) rep[i] = i;
  for (std::size_t k = count; k-- > 0;) rep[collapses_[k].u] = rep[collapses_[k].w];

  TriangleMesh mesh;
  mesh.error_bound = prefix_max_[count];
  std::vector<std::uint32_t> index(hf_.size(), UINT32_MAX);
  std::array<std::uint32_t, 3> t;
  mesh.triangles.reserve(2 * (full_vertex_count_ - count));
  for (std::uint32_t f = 0; f < full_face_slots(); ++f) {
    if (!full_face(f, t)) continue;
    const std::uint32_t a = rep[t[0]], b = rep[t[1]], c = rep[t[2]];
    if (a == b || b == c || a == c) continue;
    std::array<std::uint32_t, 3> out;
    const std::uint32_t v[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) {
      if (index[v[k]] == UINT32_MAX) {
        index[v[k]] = std::uint32_t(mesh.vertices.size());
        mesh.vertices.push_back(v[k]);
      }
      out[k] = index[v[k]];
    }
    mesh.triangles.push_back(out);
  }
  return mesh;
}

}  // namespace terralod::pm
