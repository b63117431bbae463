// Static geomorph: exact plan-view overlay of two selectively refined meshes, each piece
// triangulated without new points, heights taken from both surfaces (see geomorph.hpp).
//
// Exact arithmetic: mesh vertices are integer grid points (|coordinate| < 2^13); a crossing of
// two edges is the rational point (X / W, Y / W) with W = cross(dA, dB) (|W| < 2^29) and
// |X|, |Y| < 2^44; the orientation of three such points is a 3 x 3 determinant below 2^122,
// so every predicate is exact in 128-bit integers. Memory: see the header.
#include "terralod/pm/geomorph.hpp"

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

namespace terralod::pm {
namespace {

using i128 = __int128;

struct IP {
  std::int64_t x, y;
};

// Homogeneous point (x / w, y / w), w > 0, reduced by the gcd so that equal points are equal.
struct HP {
  i128 x, y, w;
  bool operator==(const HP&) const = default;
};

i128 iabs(i128 v) { return v < 0 ? -v : v; }
i128 gcd128(i128 a, i128 b) {
  a = iabs(a), b = iabs(b);
  while (b != 0) {
    const i128 t = a % b;
    a = b, b = t;
  }
  return a;
}

HP reduced(i128 x, i128 y, i128 w) {
  if (w < 0) x = -x, y = -y, w = -w;
  const i128 g = gcd128(gcd128(x, y), w);
  return g > 1 ? HP{x / g, y / g, w / g} : HP{x, y, w};
}

HP hp(IP p) { return {p.x, p.y, 1}; }

std::int64_t orient(IP a, IP b, IP c) { return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x); }

// Sign of the orientation of three homogeneous points (all w > 0).
int orient(const HP& a, const HP& b, const HP& c) {
  const i128 d =
      a.x * (b.y * c.w - b.w * c.y) - a.y * (b.x * c.w - b.w * c.x) + a.w * (b.x * c.y - b.y * c.x);
  return (d > 0) - (d < 0);
}

bool inside(const IP t[3], IP p) {
  return orient(t[0], t[1], p) >= 0 && orient(t[1], t[2], p) >= 0 && orient(t[2], t[0], p) >= 0;
}

// Crossing of the segments a1-a2 and b1-b2 when they cross properly (each strictly separates
// the other's endpoints).
bool crossing(IP a1, IP a2, IP b1, IP b2, HP& out) {
  const std::int64_t o1 = orient(a1, a2, b1), o2 = orient(a1, a2, b2);
  const std::int64_t o3 = orient(b1, b2, a1), o4 = orient(b1, b2, a2);
  if (!(((o1 > 0 && o2 < 0) || (o1 < 0 && o2 > 0)) && ((o3 > 0 && o4 < 0) || (o3 < 0 && o4 > 0))))
    return false;
  const i128 dax = a2.x - a1.x, day = a2.y - a1.y, dbx = b2.x - b1.x, dby = b2.y - b1.y;
  const i128 den = dax * dby - day * dbx;
  const i128 t = i128(b1.x - a1.x) * dby - i128(b1.y - a1.y) * dbx;  // a1 + dA t / den
  out = reduced(i128(a1.x) * den + dax * t, i128(a1.y) * den + day * t, den);
  return true;
}

// (y, x) lexicographic order of homogeneous points.
bool yx_less(const HP& a, const HP& b) {
  const i128 ay = a.y * b.w, by = b.y * a.w;
  if (ay != by) return ay < by;
  return a.x * b.w < b.x * a.w;
}

// Height at p of the triangle t with corner heights z: exact at corners, barycentric (exact
// integer weights, long double sums) elsewhere.
double height_in(const IP t[3], const double z[3], const HP& p) {
  if (p.w == 1)
    for (int k = 0; k < 3; ++k)
      if (p.x == t[k].x && p.y == t[k].y) return z[k];
  long double num = 0, den = 0;
  for (int k = 0; k < 3; ++k) {
    const IP a = t[(k + 1) % 3], b = t[(k + 2) % 3];
    const i128 l = i128(b.x - a.x) * (p.y - i128(a.y) * p.w) - i128(b.y - a.y) * (p.x - i128(a.x) * p.w);
    num += (long double)l * (long double)z[k];
    den += (long double)l;
  }
  return double(num / den);
}

struct HPHash {
  std::size_t operator()(const HP& p) const {
    auto mix = [](std::uint64_t h, i128 v) {
      h ^= std::uint64_t(v) + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
      h ^= std::uint64_t(v >> 64) + 0x632BE59BD9B4E019ull + (h << 6) + (h >> 2);
      return h;
    };
    return std::size_t(mix(mix(mix(0, p.x), p.y), p.w));
  }
};

// Triangulates a convex polygon given CCW, possibly with points in the middle of its edges,
// using only its points (ear clipping; an ear is never cut when the rest would be flat).
template <class Emit>
void triangulate_convex(std::vector<HP>& poly, std::vector<std::uint32_t>& ids, Emit emit) {
  auto has_area = [&](std::size_t skip) {
    const std::size_t n = poly.size();
    std::vector<std::size_t> idx;
    for (std::size_t i = 0; i < n; ++i)
      if (i != skip) idx.push_back(i);
    for (std::size_t i = 0; i < idx.size(); ++i)
      if (orient(poly[idx[i]], poly[idx[(i + 1) % idx.size()]], poly[idx[(i + 2) % idx.size()]]) > 0)
        return true;
    return false;
  };
  while (poly.size() > 3) {
    const std::size_t n = poly.size();
    bool cut = false;
    for (std::size_t i = 0; i < n && !cut; ++i) {
      const std::size_t p = (i + n - 1) % n, q = (i + 1) % n;
      if (orient(poly[p], poly[i], poly[q]) <= 0 || !has_area(i)) continue;
      emit(ids[p], ids[i], ids[q]);
      poly.erase(poly.begin() + std::ptrdiff_t(i));
      ids.erase(ids.begin() + std::ptrdiff_t(i));
      cut = true;
    }
    if (!cut) return;  // flat remainder: no area left
  }
  if (orient(poly[0], poly[1], poly[2]) > 0) emit(ids[0], ids[1], ids[2]);
}

}  // namespace

RenderMesh Geomorph::at(double alpha) const {
  if (!(alpha >= 0.0 && alpha <= 1.0)) throw std::invalid_argument("geomorph: alpha must be in [0, 1]");
  RenderMesh m;
  m.samples = samples;
  m.triangles = triangles;
  m.positions.resize(samples.size());
  const double b = 1.0 - alpha;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const auto [x, y] = transform.to_world(plan[i][0], plan[i][1]);
    m.positions[i] = {x, y, b * z_from[i] + alpha * z_to[i]};
  }
  return m;
}

Geomorph make_geomorph(const SelectiveRefinement& a, const SelectiveRefinement& b) {
  if (&a.dag() != &b.dag())
    throw std::invalid_argument("geomorph: the two selections use different collapse DAGs");
  const CollapseDag& dag = a.dag();
  const Heightfield& hf = dag.heightfield();
  if (hf.width() > 8193 || hf.height() > 8193)
    throw std::invalid_argument("geomorph: grids above 8193 samples per side are not supported");
  const std::int64_t W = hf.width();
  auto ip = [W](std::uint32_t s) { return IP{std::int64_t(s) % W, std::int64_t(s) / W}; };

  struct Tri {
    IP p[3];
    double z[3];
    std::int64_t x0, x1, y0, y1;
  };
  auto tris = [&](const SelectiveRefinement& s) {
    std::vector<Tri> out;
    out.reserve(s.active_faces().size());
    std::vector<std::uint32_t> faces = s.active_faces();
    std::sort(faces.begin(), faces.end());  // deterministic output
    for (std::uint32_t f : faces) {
      Tri t;
      for (int k = 0; k < 3; ++k) t.p[k] = ip(dag.face(f)[k]), t.z[k] = hf[dag.face(f)[k]];
      t.x0 = std::min({t.p[0].x, t.p[1].x, t.p[2].x}), t.x1 = std::max({t.p[0].x, t.p[1].x, t.p[2].x});
      t.y0 = std::min({t.p[0].y, t.p[1].y, t.p[2].y}), t.y1 = std::max({t.p[0].y, t.p[1].y, t.p[2].y});
      out.push_back(t);
    }
    return out;
  };
  const std::vector<Tri> ta = tris(a), tb = tris(b);

  // Bucket grid of M^B's triangles (16 x 16 samples per bucket).
  constexpr std::int64_t G = 16;
  const std::int64_t bx = (W + G - 1) / G, by = (hf.height() + G - 1) / G;
  std::vector<std::vector<std::uint32_t>> bucket(std::size_t(bx * by));
  for (std::uint32_t i = 0; i < tb.size(); ++i)
    for (std::int64_t y = tb[i].y0 / G; y <= tb[i].y1 / G; ++y)
      for (std::int64_t x = tb[i].x0 / G; x <= tb[i].x1 / G; ++x)
        bucket[std::size_t(y * bx + x)].push_back(i);

  Geomorph g;
  g.transform = hf.transform;
  std::vector<std::uint8_t> is_vertex(hf.size(), 0);
  for (const auto* s : {&a, &b})
    for (std::uint32_t f : s->active_faces())
      for (std::uint32_t v : dag.face(f)) is_vertex[v] = 1;
  std::unordered_map<HP, std::uint32_t, HPHash> index;
  auto vertex = [&](const HP& p, const Tri& A, const Tri& B) {
    auto [it, fresh] = index.try_emplace(p, std::uint32_t(g.plan.size()));
    if (fresh) {
      const bool sample = p.w == 1 && is_vertex[std::size_t(p.y * W + p.x)];
      g.samples.push_back(sample ? std::uint32_t(p.y * W + p.x) : Geomorph::kNoSample);
      g.plan.push_back({double(p.x) / double(p.w), double(p.y) / double(p.w)});
      g.z_from.push_back(height_in(A.p, A.z, p));
      g.z_to.push_back(height_in(B.p, B.z, p));
    }
    return it->second;
  };

  std::vector<std::uint32_t> stamp(tb.size(), 0xffffffffu);
  std::vector<HP> pts;
  std::vector<std::uint32_t> ids;
  for (std::uint32_t i = 0; i < ta.size(); ++i) {
    const Tri& A = ta[i];
    for (std::int64_t y = A.y0 / G; y <= A.y1 / G; ++y)
      for (std::int64_t x = A.x0 / G; x <= A.x1 / G; ++x)
        for (std::uint32_t j : bucket[std::size_t(y * bx + x)]) {
          if (stamp[j] == i) continue;
          stamp[j] = i;
          const Tri& B = tb[j];
          if (B.x1 < A.x0 || B.x0 > A.x1 || B.y1 < A.y0 || B.y0 > A.y1) continue;
          // Vertices of the convex piece A n B: corners inside the other triangle, crossings.
          pts.clear();
          auto add = [&](const HP& p) {
            if (std::find(pts.begin(), pts.end(), p) == pts.end()) pts.push_back(p);
          };
          for (int k = 0; k < 3; ++k) {
            if (inside(B.p, A.p[k])) add(hp(A.p[k]));
            if (inside(A.p, B.p[k])) add(hp(B.p[k]));
          }
          for (int k = 0; k < 3; ++k)
            for (int l = 0; l < 3; ++l) {
              HP c;
              if (crossing(A.p[k], A.p[(k + 1) % 3], B.p[l], B.p[(l + 1) % 3], c)) add(c);
            }
          if (pts.size() < 3) continue;
          // CCW order around the lowest point (Graham): by angle, nearer first; the points on
          // the last ray are then reversed so that the boundary comes back to the pivot.
          std::iter_swap(pts.begin(), std::min_element(pts.begin(), pts.end(), yx_less));
          const HP pv = pts[0];
          std::sort(pts.begin() + 1, pts.end(), [&](const HP& p, const HP& q) {
            const int o = orient(pv, p, q);
            return o != 0 ? o > 0 : yx_less(p, q);
          });
          std::size_t k = pts.size() - 1;
          while (k > 1 && orient(pv, pts[k - 1], pts.back()) == 0) --k;
          if (k == 1) continue;  // all collinear: no area
          std::reverse(pts.begin() + std::ptrdiff_t(k), pts.end());
          ids.clear();
          for (const HP& p : pts) ids.push_back(vertex(p, A, B));
          triangulate_convex(pts, ids, [&](std::uint32_t p, std::uint32_t q, std::uint32_t r) {
            g.triangles.push_back({p, q, r});
          });
        }
  }
  return g;
}

}  // namespace terralod::pm
