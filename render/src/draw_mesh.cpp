// Building and checking DrawMesh, the renderer's plain input (see draw_mesh.hpp).
#include "terralod/render/draw_mesh.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace terralod::render {
namespace {

bool all_finite(const std::vector<float>& v) {
  return std::all_of(v.begin(), v.end(), [](float f) { return std::isfinite(f); });
}

/// Derivative of the heights along one grid axis at (col,row): central where both
/// neighbours are valid, one-sided where one is, 0 where none is.
double grid_derivative(const pm::Heightfield& hf, int col, int row, int dc, int dr) {
  const int c0 = col - dc, r0 = row - dr, c1 = col + dc, r1 = row + dr;
  const bool has0 = c0 >= 0 && r0 >= 0 && hf.valid(c0, r0);
  const bool has1 = c1 < hf.width() && r1 < hf.height() && hf.valid(c1, r1);
  if (has0 && has1) return 0.5 * (hf.at(c1, r1) - hf.at(c0, r0));
  if (has1) return hf.at(c1, r1) - hf.at(col, row);
  if (has0) return hf.at(col, row) - hf.at(c0, r0);
  return 0.0;
}

}  // namespace

void validate(const DrawMesh& m) {
  auto fail = [](const std::string& what) { throw std::invalid_argument("DrawMesh: " + what); };
  if (m.xyz.size() % 3 != 0) fail("xyz has " + std::to_string(m.xyz.size()) + " floats, not a multiple of 3");
  const std::size_t n = m.vertex_count();
  if (n > std::numeric_limits<std::uint32_t>::max()) fail("more than 2^32 - 1 vertices");
  if (!m.z_target.empty() && m.z_target.size() != n)
    fail("z_target has " + std::to_string(m.z_target.size()) + " floats for " + std::to_string(n) +
         " vertices");
  if (!m.normals.empty() && m.normals.size() != 3 * n)
    fail("normals has " + std::to_string(m.normals.size()) + " floats for " + std::to_string(n) +
         " vertices");
  if (m.indices.size() % 3 != 0)
    fail("indices has " + std::to_string(m.indices.size()) + " entries, not a multiple of 3");
  for (std::size_t i = 0; i < m.indices.size(); ++i)
    if (m.indices[i] >= n)
      fail("index " + std::to_string(i) + " is " + std::to_string(m.indices[i]) + ", beyond the " +
           std::to_string(n) + " vertices");
  if (!all_finite(m.xyz) || !all_finite(m.z_target) || !all_finite(m.normals))
    fail("a coordinate is not finite");
  if (!std::isfinite(m.origin.x) || !std::isfinite(m.origin.y) || !std::isfinite(m.origin.z))
    fail("the origin is not finite");
}

glm::dvec3 heightfield_normal(const pm::Heightfield& hf, int col, int row) {
  assert(col >= 0 && row >= 0 && col < hf.width() && row < hf.height());
  const double dzdc = grid_derivative(hf, col, row, 1, 0), dzdr = grid_derivative(hf, col, row, 0, 1);
  // (x, y) = J (col, row) with J = [[xc, xr], [yc, yr]]; the world gradient is J^-T (dz/dc, dz/dr).
  const pm::GridTransform& t = hf.transform;
  const double det = t.determinant();
  assert(det != 0.0 && "the heightfield's GridTransform is singular");
  const double gx = (t.yr * dzdc - t.yc * dzdr) / det;
  const double gy = (-t.xr * dzdc + t.xc * dzdr) / det;
  return glm::normalize(glm::dvec3(-gx, -gy, 1.0));
}

DrawMesh make_draw_mesh(const pm::TriangleMesh& mesh, const pm::Heightfield& hf,
                        const DrawMeshOptions& options) {
  DrawMesh d;
  if (options.origin) {
    d.origin = *options.origin;
  } else {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < hf.size(); ++i)
      if (hf.valid(i)) lo = std::min(lo, hf[i]), hi = std::max(hi, hf[i]);
    const auto [cx, cy] = hf.transform.to_world(0.5 * (hf.width() - 1), 0.5 * (hf.height() - 1));
    d.origin = {cx, cy, lo <= hi ? 0.5 * (lo + hi) : 0.0};
  }
  const std::size_t n = mesh.vertices.size();
  d.xyz.resize(3 * n);
  if (options.sample_normals) d.normals.resize(3 * n);
  for (std::size_t v = 0; v < n; ++v) {
    const std::uint32_t s = mesh.vertices[v];
    assert(s < hf.size() && "TriangleMesh vertex outside the heightfield");
    const int col = int(s % std::uint32_t(hf.width())), row = int(s / std::uint32_t(hf.width()));
    const auto [x, y] = hf.transform.to_world(col, row);
    d.xyz[3 * v + 0] = float(x - d.origin.x);
    d.xyz[3 * v + 1] = float(y - d.origin.y);
    d.xyz[3 * v + 2] = float(hf[s] - d.origin.z);
    if (options.sample_normals) {
      const glm::dvec3 nrm = heightfield_normal(hf, col, row);
      d.normals[3 * v + 0] = float(nrm.x);
      d.normals[3 * v + 1] = float(nrm.y);
      d.normals[3 * v + 2] = float(nrm.z);
    }
  }
  const bool flip = hf.transform.determinant() < 0.0;
  d.indices.reserve(3 * mesh.triangles.size());
  for (const auto& t : mesh.triangles) {
    d.indices.push_back(t[0]);
    d.indices.push_back(flip ? t[2] : t[1]);
    d.indices.push_back(flip ? t[1] : t[2]);
  }
  return d;
}

std::vector<float> triangle_normals(const DrawMesh& m) {
  const std::size_t n = m.vertex_count();
  std::vector<double> acc(3 * n, 0.0);
  for (std::size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const std::uint32_t i[3] = {m.indices[t], m.indices[t + 1], m.indices[t + 2]};
    glm::dvec3 p[3];
    for (int k = 0; k < 3; ++k) p[k] = {m.xyz[3 * i[k]], m.xyz[3 * i[k] + 1], m.xyz[3 * i[k] + 2]};
    glm::dvec3 c = glm::cross(p[1] - p[0], p[2] - p[0]);  // length = 2 x area
    if (c.z < 0.0) c = -c;                                // normals point up whatever the winding
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) acc[3 * i[k] + a] += c[a];
  }
  std::vector<float> out(3 * n);
  for (std::size_t v = 0; v < n; ++v) {
    glm::dvec3 s(acc[3 * v], acc[3 * v + 1], acc[3 * v + 2]);
    const double len = glm::length(s);
    s = len > 0.0 ? s / len : glm::dvec3(0.0, 0.0, 1.0);
    out[3 * v] = float(s.x), out[3 * v + 1] = float(s.y), out[3 * v + 2] = float(s.z);
  }
  return out;
}

void fill_draw_geometry(std::span<const pm::Vec3> positions,
                        std::span<const std::array<std::uint32_t, 3>> triangles, const glm::dvec3& o,
                        bool flip, DrawMesh& dm) {
  const std::size_t nv = positions.size();
  dm.origin = o;
  dm.z_target.clear();
  dm.xyz.resize(nv * 3);
  for (std::size_t v = 0; v < nv; ++v) {
    dm.xyz[3 * v] = float(positions[v].x - o.x);
    dm.xyz[3 * v + 1] = float(positions[v].y - o.y);
    dm.xyz[3 * v + 2] = float(positions[v].z - o.z);
  }
  dm.indices.resize(triangles.size() * 3);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    dm.indices[3 * f] = triangles[f][0];
    dm.indices[3 * f + 1] = triangles[f][flip ? 2 : 1];
    dm.indices[3 * f + 2] = triangles[f][flip ? 1 : 2];
  }
}

void fill_draw_mesh(const blocks::DrawnMesh& m, const glm::dvec3& o, bool flip, DrawMesh& dm) {
  fill_draw_geometry(m.positions, m.triangles, o, flip, dm);
  const std::size_t nv = m.positions.size();
  // Normals in double from the world positions (the floats lose the small slopes far away).
  std::vector<glm::dvec3> acc(nv, glm::dvec3(0.0));
  for (std::size_t f = 0; f < m.triangles.size(); ++f) {
    const std::uint32_t* i = &dm.indices[3 * f];
    const pm::Vec3 &a = m.positions[i[0]], &b = m.positions[i[1]], &c = m.positions[i[2]];
    const glm::dvec3 n = glm::cross(glm::dvec3(b.x - a.x, b.y - a.y, b.z - a.z),
                                    glm::dvec3(c.x - a.x, c.y - a.y, c.z - a.z));  // |n| = 2 area
    for (int j = 0; j < 3; ++j) acc[i[j]] += n;
  }
  dm.normals.resize(nv * 3);
  for (std::size_t v = 0; v < nv; ++v) {
    const double len = glm::length(acc[v]);
    const glm::dvec3 n = len > 0 && acc[v].z > 0 ? acc[v] / len : glm::dvec3(0, 0, 1);
    dm.normals[3 * v] = float(n.x), dm.normals[3 * v + 1] = float(n.y), dm.normals[3 * v + 2] = float(n.z);
  }
}

pm::TriangleMeshData world_mesh(const DrawMesh& dm) {
  pm::TriangleMeshData d;
  d.positions.resize(dm.vertex_count());
  for (std::size_t v = 0; v < dm.vertex_count(); ++v)
    d.positions[v] = {dm.origin.x + double(dm.xyz[3 * v]), dm.origin.y + double(dm.xyz[3 * v + 1]),
                      dm.origin.z + double(dm.xyz[3 * v + 2])};
  d.triangles.resize(dm.triangle_count());
  for (std::size_t f = 0; f < dm.triangle_count(); ++f)
    d.triangles[f] = {dm.indices[3 * f], dm.indices[3 * f + 1], dm.indices[3 * f + 2]};
  return d;
}

}  // namespace terralod::render
