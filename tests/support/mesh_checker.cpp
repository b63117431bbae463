// Independent brute-force checker of a triangle mesh over a heightfield (see mesh_checker.hpp).
#include "mesh_checker.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <numeric>
#include <sstream>

namespace terralod::test {
namespace {

struct Pt {
  std::int64_t x = 0, y = 0;
};

// Twice the signed area of (a,b,c); > 0 when c is left of a->b (CCW in (col,row)).
std::int64_t orient(Pt a, Pt b, Pt c) { return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x); }

// Half-open rule for a point exactly on the line of edge a->b: it counts as inside when the
// point pushed by an infinitesimal step (1, delta), delta << 1, moves to the left of a->b.
// The sign of orient(a, b, p + eps (1, delta)) - orient(a, b, p) is that of
// -(b.y - a.y) + delta (b.x - a.x).
bool edge_owns(Pt a, Pt b) {
  const std::int64_t dy = b.y - a.y;
  return dy != 0 ? dy < 0 : b.x > a.x;
}

std::int64_t floor_div(std::int64_t a, std::int64_t b) {  // b > 0
  const std::int64_t q = a / b;
  return (a % b != 0 && a < 0) ? q - 1 : q;
}

std::string where(std::int64_t col, std::int64_t row) {
  std::string s(1, '(');  // appended piecewise: GCC 12 warns falsely (-Wrestrict) on "(" + string
  s += std::to_string(col);
  s += ',';
  s += std::to_string(row);
  s += ')';
  return s;
}

// Calls f(x, y, error) for every valid sample (x, y) in the closed triangle (a, b, c), which
// must have area2 = orient(a, b, c) > 0. Each row of the bounding box is narrowed to the span
// where all three edge functions are >= 0, computed with exact integer floor/ceil divisions
// (a long sliver would otherwise cost its whole bounding box); every sample in the span is
// still tested with exact integer orientations, which also give its barycentric weights. The
// interpolated height is compared in long double.
template <class F>
void for_samples_in(const pm::Heightfield& hf, Pt a, Pt b, Pt c, F&& f) {
  const std::int64_t W = hf.width();
  const long double za = hf.at(int(a.x), int(a.y)), zb = hf.at(int(b.x), int(b.y)),
                    zc = hf.at(int(c.x), int(c.y));
  const long double A = (long double)orient(a, b, c);
  const std::int64_t x0 = std::min({a.x, b.x, c.x}), x1 = std::max({a.x, b.x, c.x});
  const std::int64_t y0 = std::min({a.y, b.y, c.y}), y1 = std::max({a.y, b.y, c.y});
  const Pt from[3] = {a, b, c}, to[3] = {b, c, a};
  for (std::int64_t y = y0; y <= y1; ++y) {
    // orient(s, e, (x, y)) = (e.x - s.x)(y - s.y) - (e.y - s.y)(x - s.x) = k x + m.
    std::int64_t lo = x0, hi = x1;
    for (int e = 0; e < 3; ++e) {
      const std::int64_t k = -(to[e].y - from[e].y);
      const std::int64_t m = (to[e].x - from[e].x) * (y - from[e].y) + (to[e].y - from[e].y) * from[e].x;
      if (k > 0)
        lo = std::max(lo, -floor_div(m, k));  // x >= ceil(-m / k)
      else if (k < 0)
        hi = std::min(hi, floor_div(m, -k));  // x <= floor(m / -k)
      else if (m < 0)
        hi = lo - 1;
    }
    for (std::int64_t x = lo; x <= hi; ++x) {
      const Pt p{x, y};
      const std::int64_t wa = orient(b, c, p), wb = orient(c, a, p), wc = orient(a, b, p);
      if (wa < 0 || wb < 0 || wc < 0) continue;
      const std::size_t idx = std::size_t(y * W + x);
      if (!hf.valid(idx)) continue;  // a triangle over a hole: check_mesh reports it by centroids
      const long double num = (long double)wa * za + (long double)wb * zb + (long double)wc * zc;
      f(x, y, std::fabs(num - A * (long double)hf[idx]) / A);
    }
  }
}

// D times the full-resolution surface at (X/D, Y/D): the point is located in its cell and in
// the cell's triangle, and only corners with a non-zero barycentric weight are read (so a
// point on the edge of a hole reads no invalid sample). False if such a corner is invalid.
bool full_surface(const pm::Heightfield& hf, std::int64_t X, std::int64_t Y, std::int64_t D,
                  long double& out) {
  const std::int64_t W = hf.width(), H = hf.height();
  std::int64_t i = floor_div(X, D), j = floor_div(Y, D);
  if (i == W - 1) --i;
  if (j == H - 1) --j;
  if (i < 0 || j < 0 || i > W - 2 || j > H - 2) return false;
  const std::int64_t fx = X - i * D, fy = Y - j * D;  // in [0, D]
  struct Corner {
    std::int64_t di, dj, w;
  } c[3];
  if (fx >= fy)
    c[0] = {0, 0, D - fx}, c[1] = {1, 0, fx - fy}, c[2] = {1, 1, fy};
  else
    c[0] = {0, 0, D - fy}, c[1] = {0, 1, fy - fx}, c[2] = {1, 1, fx};
  long double sum = 0;
  for (const Corner& k : c) {
    if (k.w == 0) continue;
    if (!hf.valid(int(i + k.di), int(j + k.dj))) return false;
    sum += (long double)k.w * (long double)hf.at(int(i + k.di), int(j + k.dj));
  }
  out = sum;
  return true;
}

// Compares the edge a-b with the full-resolution surface at every crossing with a vertical
// (x = i), horizontal (y = j) or diagonal (x - y = k) grid line. A crossing is the point
// (X/D, Y/D) with X = a.x D + s dx, Y = a.y D + s dy for s = 1..D-1, where D is how much the
// line family's coordinate changes along the edge. Calls f(X, Y, D, defined, error); defined
// is false where the surface is a hole.
template <class F>
void for_crossings(const pm::Heightfield& hf, Pt a, Pt b, F&& f) {
  const std::int64_t dx = b.x - a.x, dy = b.y - a.y;
  const long double za = hf.at(int(a.x), int(a.y)), zb = hf.at(int(b.x), int(b.y));
  const std::int64_t Ds[3] = {std::llabs(dx), std::llabs(dy), std::llabs(dx - dy)};
  for (std::int64_t D : Ds)
    for (std::int64_t s = 1; s < D; ++s) {
      const std::int64_t X = a.x * D + s * dx, Y = a.y * D + s * dy;
      long double full;
      if (!full_surface(hf, X, Y, D, full)) {
        f(X, Y, D, false, 0.0L);
        continue;
      }
      const long double edge = za * (long double)(D - s) + zb * (long double)s;
      f(X, Y, D, true, std::fabs(edge - full) / (long double)D);
    }
}

class Checker {
 public:
  Checker(const pm::Heightfield& hf, const pm::TriangleMesh& mesh, const CheckOptions& opt)
      : hf_(hf), mesh_(mesh), opt_(opt), W_(hf.width()), H_(hf.height()) {}

  MeshCheck run() {
    r_.vertices = mesh_.vertices.size();
    r_.triangles = mesh_.triangles.size();
    make_domain();
    check_vertices();
    scan_triangles();
    check_edges();
    check_duplicate_triangles();
    return r_;
  }

 private:
  // Only the first defect is described; callers test want() first so that no message is built
  // on a hot path once one is recorded.
  bool want() const { return r_.first_problem.empty(); }
  void problem(const std::string& what) {
    if (want()) r_.first_problem = what;
  }

  std::size_t cells_x() const { return W_ > 1 ? std::size_t(W_ - 1) : 0; }
  std::size_t face_slots() const {
    return W_ > 1 && H_ > 1 ? 2 * std::size_t(W_ - 1) * std::size_t(H_ - 1) : 0;
  }
  std::size_t face_id(std::int64_t i, std::int64_t j, int k) const {
    return 2 * (std::size_t(j) * cells_x() + std::size_t(i)) + k;
  }
  bool valid(std::int64_t col, std::int64_t row) const { return hf_.valid(int(col), int(row)); }

  // Domain faces: all corners valid and not excluded.
  void make_domain() {
    in_domain_.assign(face_slots(), 0);
    domain_sample_.assign(hf_.size(), 0);
    for (std::int64_t j = 0; j + 1 < H_; ++j)
      for (std::int64_t i = 0; i + 1 < W_; ++i) {
        const bool v00 = valid(i, j), v10 = valid(i + 1, j), v01 = valid(i, j + 1), v11 = valid(i + 1, j + 1);
        in_domain_[face_id(i, j, 0)] = v00 && v10 && v11;
        in_domain_[face_id(i, j, 1)] = v00 && v11 && v01;
      }
    for (std::uint32_t f : opt_.excluded_faces)
      if (f < in_domain_.size()) in_domain_[f] = 0;
    for (std::int64_t j = 0; j + 1 < H_; ++j)
      for (std::int64_t i = 0; i + 1 < W_; ++i) {
        const std::size_t s00 = std::size_t(j) * W_ + i, s10 = s00 + 1, s01 = s00 + W_, s11 = s01 + 1;
        if (in_domain_[face_id(i, j, 0)]) domain_sample_[s00] = domain_sample_[s10] = domain_sample_[s11] = 1;
        if (in_domain_[face_id(i, j, 1)]) domain_sample_[s00] = domain_sample_[s11] = domain_sample_[s01] = 1;
      }
    r_.domain_faces = std::size_t(std::count(in_domain_.begin(), in_domain_.end(), 1));
    r_.domain_area2 = std::int64_t(r_.domain_faces);
    bool integers = true;
    double zmax = 0.0;
    for (std::size_t s = 0; s < hf_.size(); ++s)
      if (hf_.valid(s)) {
        integers = integers && hf_[s] == std::floor(hf_[s]);
        zmax = std::max(zmax, std::abs(hf_[s]));
      }
    r_.tolerance = integers ? 0.0 : 1e-12 * std::max(1.0, zmax);
  }

  void check_vertices() {
    vertex_ok_.assign(mesh_.vertices.size(), 0);
    for (std::size_t k = 0; k < mesh_.vertices.size(); ++k) {
      const std::uint32_t s = mesh_.vertices[k];
      if (s >= hf_.size() || !hf_.valid(s)) {
        ++r_.bad_vertices;
        if (want())
          problem("vertex " + std::to_string(k) + " is sample " + std::to_string(s) +
                  (s >= hf_.size() ? ", out of range" : ", not a valid sample"));
        continue;
      }
      vertex_ok_[k] = 1;
    }
    std::vector<std::uint32_t> sorted = mesh_.vertices;
    std::sort(sorted.begin(), sorted.end());
    for (std::size_t k = 1; k < sorted.size(); ++k)
      if (sorted[k] == sorted[k - 1]) {
        ++r_.duplicate_vertices;
        if (want()) problem("sample " + std::to_string(sorted[k]) + " is listed twice as a vertex");
      }
  }

  Pt point_of(std::uint32_t sample) const {
    return Pt{std::int64_t(sample % std::uint32_t(W_)), std::int64_t(sample / std::uint32_t(W_))};
  }

  // Resolves a triangle's corners to samples; false (and counted) when an index is bad.
  bool corners(const std::array<std::uint32_t, 3>& t, std::uint32_t s[3]) {
    for (int k = 0; k < 3; ++k)
      if (t[k] >= mesh_.vertices.size()) {
        ++r_.bad_indices;
        if (want())
          problem("a triangle refers to vertex " + std::to_string(t[k]) + " of " +
                  std::to_string(mesh_.vertices.size()));
        return false;
      }
    for (int k = 0; k < 3; ++k) {
      if (!vertex_ok_[t[k]]) return false;
      s[k] = mesh_.vertices[t[k]];
    }
    return true;
  }

  void scan_triangles() {
    sample_hit_.assign(hf_.size(), 0);
    face_cover_.assign(face_slots(), 0);
    long double worst = -1;
    for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
      std::uint32_t s[3];
      if (!corners(mesh_.triangles[t], s)) continue;
      const Pt a = point_of(s[0]), b = point_of(s[1]), c = point_of(s[2]);
      const std::int64_t area2 = orient(a, b, c);
      r_.area2_sum += area2;
      if (area2 <= 0) {
        (area2 == 0 ? r_.degenerate : r_.flipped) += 1;
        if (want())
          problem(std::string(area2 == 0 ? "degenerate" : "flipped") + " triangle " + std::to_string(t) +
                  ": " + where(a.x, a.y) + " " + where(b.x, b.y) + " " + where(c.x, c.y));
        continue;
      }
      const std::int64_t x0 = std::min({a.x, b.x, c.x}), x1 = std::max({a.x, b.x, c.x});
      const std::int64_t y0 = std::min({a.y, b.y, c.y}), y1 = std::max({a.y, b.y, c.y});
      // (a) Samples in the closed triangle.
      for_samples_in(hf_, a, b, c, [&](std::int64_t x, std::int64_t y, long double e) {
        sample_hit_[std::size_t(y) * W_ + x] = 1;
        ++r_.samples_measured;
        if (e > worst) {
          worst = e;
          r_.worst_sample_col = int(x), r_.worst_sample_row = int(y);
        }
      });
      // (b) Face centroids, in coordinates scaled by 3 so that they are integers:
      // face (i,j,0) has centroid (3i+2, 3j+1), face (i,j,1) has (3i+1, 3j+2).
      const Pt A3{3 * a.x, 3 * a.y}, B3{3 * b.x, 3 * b.y}, C3{3 * c.x, 3 * c.y};
      const bool own_ab = edge_owns(A3, B3), own_bc = edge_owns(B3, C3), own_ca = edge_owns(C3, A3);
      for (std::int64_t j = y0; j < y1; ++j)
        for (std::int64_t i = x0; i < x1; ++i)
          for (int k = 0; k < 2; ++k) {
            const Pt p{3 * i + (k == 0 ? 2 : 1), 3 * j + (k == 0 ? 1 : 2)};
            const std::int64_t e0 = orient(A3, B3, p), e1 = orient(B3, C3, p), e2 = orient(C3, A3, p);
            if (!(e0 > 0 || (e0 == 0 && own_ab)) || !(e1 > 0 || (e1 == 0 && own_bc)) ||
                !(e2 > 0 || (e2 == 0 && own_ca)))
              continue;
            const std::size_t f = face_id(i, j, k);
            if (!in_domain_[f]) {
              ++r_.covered_outside;
              if (want())
                problem("triangle " + std::to_string(t) + " covers face " + std::to_string(f) + " of cell " +
                        where(i, j) + ", which is outside the domain");
            } else if (face_cover_[f] < 255) {
              ++face_cover_[f];
            }
          }
    }
    r_.max_sample_error = worst < 0 ? 0.0 : double(worst);
    for (std::size_t f = 0; f < face_cover_.size(); ++f) {
      if (!in_domain_[f]) continue;
      if (face_cover_[f] == 0) {
        ++r_.uncovered_faces;
        if (want())
          problem("face " + std::to_string(f) + " of cell " +
                  where(std::int64_t((f / 2) % cells_x()), std::int64_t(f / 2 / cells_x())) +
                  " is covered by no triangle (a gap)");
      } else if (face_cover_[f] > 1) {
        ++r_.overlapped_faces;
        if (want())
          problem("face " + std::to_string(f) + " of cell " +
                  where(std::int64_t((f / 2) % cells_x()), std::int64_t(f / 2 / cells_x())) +
                  " is covered by " + std::to_string(face_cover_[f]) + " triangles (an overlap)");
      }
    }
    for (std::size_t s = 0; s < hf_.size(); ++s)
      if (domain_sample_[s] && !sample_hit_[s]) {
        ++r_.uncovered_samples;
        if (want())
          problem("sample " + where(std::int64_t(s % W_), std::int64_t(s / W_)) + " lies in no triangle");
      }
    if (r_.area2_sum != r_.domain_area2 && want())
      problem("triangle areas sum to " + std::to_string(r_.area2_sum) + "/2 but the domain has area " +
              std::to_string(r_.domain_area2) + "/2");
  }

  // Face containing the point (X/4, Y/4), or -1 outside the grid. Used only for points that
  // lie strictly inside a face (never on a grid edge).
  std::int64_t face_at_quarter(std::int64_t X, std::int64_t Y) const {
    const std::int64_t i = floor_div(X, 4), j = floor_div(Y, 4);
    if (i < 0 || j < 0 || i >= W_ - 1 || j >= H_ - 1) return -1;
    const std::int64_t fx = X - 4 * i, fy = Y - 4 * j;
    return std::int64_t(face_id(i, j, fx > fy ? 0 : 1));
  }
  bool domain_face_at_quarter(std::int64_t X, std::int64_t Y) const {
    const std::int64_t f = face_at_quarter(X, Y);
    return f >= 0 && in_domain_[std::size_t(f)];
  }

  // True when the segment a->b runs along grid edges that all separate a domain face on their
  // left from a non-domain face (or the outside) on their right.
  bool on_domain_boundary(Pt a, Pt b) const {
    const std::int64_t dx = b.x - a.x, dy = b.y - a.y;
    const std::int64_t g = std::gcd(std::llabs(dx), std::llabs(dy));
    if (g == 0) return false;
    const std::int64_t sx = dx / g, sy = dy / g;
    const bool grid_edge = (std::llabs(sx) + std::llabs(sy) == 1) || (sx == sy && std::llabs(sx) == 1);
    if (!grid_edge) return false;
    for (std::int64_t k = 0; k < g; ++k) {
      const std::int64_t px = a.x + k * sx, py = a.y + k * sy;
      // Midpoint of the unit edge, pushed a quarter step to the left (-sy, sx) or the right.
      const std::int64_t mx4 = 4 * px + 2 * sx, my4 = 4 * py + 2 * sy;
      if (!domain_face_at_quarter(mx4 - sy, my4 + sx)) return false;
      if (domain_face_at_quarter(mx4 + sy, my4 - sx)) return false;
    }
    return true;
  }

  void check_edges() {
    // Key: min sample << 33 | max sample << 1 | (1 when directed max -> min).
    std::vector<std::uint64_t> keys;
    keys.reserve(3 * mesh_.triangles.size());
    for (const auto& t : mesh_.triangles) {
      std::uint32_t s[3];
      bool good = true;
      for (int k = 0; k < 3 && good; ++k) {
        good = t[k] < mesh_.vertices.size() && vertex_ok_[t[k]];
        if (good) s[k] = mesh_.vertices[t[k]];
      }
      if (!good) continue;
      for (int k = 0; k < 3; ++k) {
        const std::uint64_t from = s[k], to = s[(k + 1) % 3];
        if (from == to) continue;
        keys.push_back(from < to ? (from << 33 | to << 1) : (to << 33 | from << 1 | 1));
      }
    }
    std::sort(keys.begin(), keys.end());
    long double worst = -1;
    for (std::size_t k = 0; k < keys.size();) {
      const std::uint64_t edge = keys[k] >> 1;
      std::size_t forward = 0, backward = 0;
      for (; k < keys.size() && (keys[k] >> 1) == edge; ++k) (keys[k] & 1 ? backward : forward) += 1;
      const std::uint32_t lo = std::uint32_t(edge >> 32), hi = std::uint32_t(edge & 0xFFFFFFFFu);
      const Pt plo = point_of(lo), phi = point_of(hi);
      ++r_.edges;
      const std::size_t uses = forward + backward;
      if (uses == 1) {
        ++r_.boundary_edges;
        const bool ok = forward ? on_domain_boundary(plo, phi) : on_domain_boundary(phi, plo);
        if (!ok) {
          ++r_.open_edges_off_boundary;
          if (want())
            problem("edge " + where(plo.x, plo.y) + "-" + where(phi.x, phi.y) +
                    " has one triangle but is not on the domain boundary (a crack or T-junction)");
        }
      } else if (uses == 2 && (forward == 2 || backward == 2)) {
        ++r_.misoriented_edges;
        if (want())
          problem("edge " + where(plo.x, plo.y) + "-" + where(phi.x, phi.y) +
                  " is used twice in the same direction");
      } else if (uses > 2) {
        ++r_.non_manifold_edges;
        if (want())
          problem("edge " + where(plo.x, plo.y) + "-" + where(phi.x, phi.y) + " is used by " +
                  std::to_string(uses) + " triangles");
      }
      if (opt_.continuous) crossings(plo, phi, worst);
    }
    r_.max_crossing_error = worst < 0 ? 0.0 : double(worst);
  }

  void crossings(Pt a, Pt b, long double& worst) {
    for_crossings(
        hf_, a, b, [&](std::int64_t X, std::int64_t Y, std::int64_t D, bool defined, long double e) {
          if (!defined) {
            ++r_.edges_over_holes;
            if (want())
              problem("edge " + where(a.x, a.y) + "-" + where(b.x, b.y) + " passes over a hole near " +
                      where(floor_div(X, D), floor_div(Y, D)));
            return;
          }
          ++r_.crossings_measured;
          if (e > worst) {
            worst = e;
            r_.worst_crossing_col = double(X) / double(D), r_.worst_crossing_row = double(Y) / double(D);
          }
        });
  }

  void check_duplicate_triangles() {
    std::vector<std::array<std::uint32_t, 3>> sets;
    sets.reserve(mesh_.triangles.size());
    for (const auto& t : mesh_.triangles) {
      if (t[0] >= mesh_.vertices.size() || t[1] >= mesh_.vertices.size() || t[2] >= mesh_.vertices.size())
        continue;
      std::array<std::uint32_t, 3> s = {mesh_.vertices[t[0]], mesh_.vertices[t[1]], mesh_.vertices[t[2]]};
      std::sort(s.begin(), s.end());
      sets.push_back(s);
    }
    std::sort(sets.begin(), sets.end());
    for (std::size_t k = 1; k < sets.size(); ++k)
      if (sets[k] == sets[k - 1]) {
        ++r_.duplicate_triangles;
        if (want())
          problem("triangle on samples " + std::to_string(sets[k][0]) + ", " + std::to_string(sets[k][1]) +
                  ", " + std::to_string(sets[k][2]) + " appears twice");
      }
  }

  const pm::Heightfield& hf_;
  const pm::TriangleMesh& mesh_;
  const CheckOptions& opt_;
  const std::int64_t W_, H_;
  MeshCheck r_;
  std::vector<std::uint8_t> in_domain_, domain_sample_, vertex_ok_, sample_hit_, face_cover_;
};

}  // namespace

bool MeshCheck::topology_ok() const {
  return flipped == 0 && degenerate == 0 && area2_sum == domain_area2 && uncovered_faces == 0 &&
         overlapped_faces == 0 && covered_outside == 0 && uncovered_samples == 0 && edges_over_holes == 0 &&
         non_manifold_edges == 0 && misoriented_edges == 0 && open_edges_off_boundary == 0 &&
         duplicate_vertices == 0 && duplicate_triangles == 0 && bad_vertices == 0 && bad_indices == 0;
}

bool MeshCheck::ok(double bound, bool continuous) const {
  return topology_ok() && max_sample_error <= bound + tolerance &&
         (!continuous || max_crossing_error <= bound + tolerance);
}

std::string MeshCheck::describe() const {
  std::ostringstream o;
  o.precision(17);
  o << "mesh check: " << vertices << " vertices, " << triangles << " triangles, " << edges << " edges ("
    << boundary_edges << " boundary), domain of " << domain_faces << " grid faces\n"
    << "  max sample error   " << max_sample_error << " m at (" << worst_sample_col << "," << worst_sample_row
    << "), " << samples_measured << " samples measured\n"
    << "  max crossing error " << max_crossing_error << " m at (" << worst_crossing_col << ","
    << worst_crossing_row << "), " << crossings_measured << " crossings measured; tolerance " << tolerance
    << "\n"
    << "  flipped " << flipped << ", degenerate " << degenerate << ", 2*area " << area2_sum << " vs domain "
    << domain_area2 << "\n"
    << "  uncovered faces " << uncovered_faces << ", overlapped faces " << overlapped_faces
    << ", covered outside " << covered_outside << ", uncovered samples " << uncovered_samples
    << ", edges over holes " << edges_over_holes << "\n"
    << "  non-manifold edges " << non_manifold_edges << ", misoriented edges " << misoriented_edges
    << ", open edges off the boundary " << open_edges_off_boundary << "\n"
    << "  duplicate vertices " << duplicate_vertices << ", duplicate triangles " << duplicate_triangles
    << ", bad vertices " << bad_vertices << ", bad indices " << bad_indices << "\n"
    << "  first problem: " << (first_problem.empty() ? "none" : first_problem);
  return o.str();
}

TriangleError triangle_error(const pm::Heightfield& hf, std::uint32_t s0, std::uint32_t s1, std::uint32_t s2,
                             bool continuous) {
  const std::uint32_t W = std::uint32_t(hf.width());
  Pt p[3] = {{s0 % W, s0 / W}, {s1 % W, s1 / W}, {s2 % W, s2 / W}};
  TriangleError out;
  if (orient(p[0], p[1], p[2]) < 0) std::swap(p[1], p[2]);
  if (orient(p[0], p[1], p[2]) > 0)
    for_samples_in(hf, p[0], p[1], p[2], [&](std::int64_t, std::int64_t, long double e) {
      out.samples = std::max(out.samples, double(e));
    });
  if (continuous)
    for (int k = 0; k < 3; ++k)
      for_crossings(hf, p[k], p[(k + 1) % 3],
                    [&](std::int64_t, std::int64_t, std::int64_t, bool defined, long double e) {
                      if (!defined)
                        out.over_hole = true;
                      else
                        out.crossings = std::max(out.crossings, double(e));
                    });
  return out;
}

double edge_error(const pm::Heightfield& hf, std::uint32_t s0, std::uint32_t s1, bool* over_hole) {
  const std::uint32_t W = std::uint32_t(hf.width());
  double out = 0.0;
  for_crossings(hf, Pt{s0 % W, s0 / W}, Pt{s1 % W, s1 / W},
                [&](std::int64_t, std::int64_t, std::int64_t, bool defined, long double e) {
                  if (!defined && over_hole) *over_hole = true;
                  if (defined) out = std::max(out, double(e));
                });
  return out;
}

MeshCheck check_mesh(const pm::Heightfield& hf, const pm::TriangleMesh& mesh, const CheckOptions& options) {
  return Checker(hf, mesh, options).run();
}

}  // namespace terralod::test
