// Draped lines (object_drape.hpp): a polyline's ribbon cut into convex pieces (segment
// rectangles, round joins), each clipped in plan against the drawn triangles under it
// (Sutherland-Hodgman) and lifted onto their planes. Memory: the output plus one piece's
// scratch (polygons, triangle ids).
#include "terralod/blocks/object_drape.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

namespace terralod::blocks {
namespace {

struct P2 {
  double x = 0, y = 0;
};
using Polygon = std::vector<P2>;

double cross(P2 o, P2 a, P2 b) { return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x); }

// Keeps the part of the convex polygon `in` on the inner side of the line through e0, e1 (the
// side where sign * cross(e0, e1, q) >= 0). The line is taken in a canonical direction (smaller
// endpoint first), so the two triangles sharing an edge compute the same distances, negated.
void clip_half_plane(const Polygon& in, P2 e0, P2 e1, double sign, Polygon& out) {
  if (e1.x < e0.x || (e1.x == e0.x && e1.y < e0.y)) {
    std::swap(e0, e1);
    sign = -sign;
  }
  out.clear();
  const std::size_t n = in.size();
  for (std::size_t i = 0; i < n; ++i) {
    const P2 a = in[i], b = in[(i + 1) % n];
    const double da = sign * cross(e0, e1, a), db = sign * cross(e0, e1, b);
    if (da >= 0) out.push_back(a);
    if ((da > 0 && db < 0) || (da < 0 && db > 0)) {
      const double t = da / (da - db);
      out.push_back({a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)});
    }
  }
}

class Draper {
 public:
  Draper(const TerrainRuntime& rt, ObjectMesh& out) : rt_(rt), mesh_(rt.drawn_mesh()), out_(out) {
    assert(out.normals.size() == out.positions.size() && "ObjectMesh: normals per vertex");
  }

  void line(std::span<const WorldPoint> line, double width_m, std::uint32_t object) {
    assert(std::isfinite(width_m) && width_m > 0 && "drape: width_m finite and > 0");
    const double h = width_m / 2;
    points_.clear();
    for (const WorldPoint& p : line) {
      assert(std::isfinite(p.x) && std::isfinite(p.y) && "drape: points finite");
      if (points_.empty() || points_.back().x != p.x || points_.back().y != p.y)
        points_.push_back({p.x, p.y});
    }
    for (std::size_t i = 0; i + 1 < points_.size(); ++i) {
      const P2 a = points_[i], b = points_[i + 1];
      const P2 n0 = left_normal(a, b);
      piece_ = {{a.x - h * n0.x, a.y - h * n0.y},
                {b.x - h * n0.x, b.y - h * n0.y},
                {b.x + h * n0.x, b.y + h * n0.y},
                {a.x + h * n0.x, a.y + h * n0.y}};
      join_.clear();
      if (i + 2 < points_.size()) join(a, b, points_[i + 2], h);
      drape_segment(object);
    }
  }

  DrapeStats stats;

 private:
  static P2 left_normal(P2 a, P2 b) {
    const double dx = b.x - a.x, dy = b.y - a.y, len = std::hypot(dx, dy);
    return {-dy / len, dx / len};
  }

  // The round join at b between a -> b and b -> c: the sector on the outer side of the turn,
  // from the end of the first rectangle to the start of the second (their corners exactly).
  void join(P2 a, P2 b, P2 c, double h) {
    const P2 n0 = left_normal(a, b), n1 = left_normal(b, c);
    const double d0x = b.x - a.x, d0y = b.y - a.y, d1x = c.x - b.x, d1y = c.y - b.y;
    const double turn = std::atan2(d0x * d1y - d0y * d1x, d0x * d1x + d0y * d1y);
    if (turn == 0) return;
    // Counter-clockwise from `from` to `to` around b: a left turn's outer side is the right.
    const P2 from = turn > 0 ? P2{-n0.x, -n0.y} : n1, to = turn > 0 ? P2{-n1.x, -n1.y} : n0;
    const double sweep = std::abs(turn), start = std::atan2(from.y, from.x);
    const int steps = std::max(1, int(std::ceil(sweep / (std::numbers::pi / 8))));
    join_.push_back(b);
    join_.push_back({b.x + h * from.x, b.y + h * from.y});
    for (int k = 1; k < steps; ++k) {
      const double t = start + sweep * k / steps;
      join_.push_back({b.x + h * std::cos(t), b.y + h * std::sin(t)});
    }
    join_.push_back({b.x + h * to.x, b.y + h * to.y});
  }

  struct Box {
    double x0, y0, x1, y1;
  };
  static Box box_of(const Polygon& p) {
    Box b{p[0].x, p[0].y, p[0].x, p[0].y};
    for (const P2& q : p) {
      b.x0 = std::min(b.x0, q.x), b.x1 = std::max(b.x1, q.x);
      b.y0 = std::min(b.y0, q.y), b.y1 = std::max(b.y1, q.y);
    }
    return b;
  }

  // Clips piece_ (a segment's rectangle) and join_ (its join at the far end, or empty), both
  // convex and CCW in world plan, against the drawn triangles under the segment's box (one
  // index query for both).
  void drape_segment(std::uint32_t object) {
    const Box rect = box_of(piece_);
    Box all = rect, join = rect;
    stats.pieces += join_.empty() ? 1 : 2;
    if (!join_.empty()) {
      join = box_of(join_);
      all = {std::min(rect.x0, join.x0), std::min(rect.y0, join.y0), std::max(rect.x1, join.x1),
             std::max(rect.y1, join.y1)};
    }
    rt_.drawn_triangles_in(all.x0, all.y0, all.x1, all.y1, ids_);
    for (const std::uint32_t f : ids_) {
      const auto& t = mesh_.triangles[f];
      const pm::Vec3 &A = mesh_.positions[t[0]], &B = mesh_.positions[t[1]], &C = mesh_.positions[t[2]];
      const Box tb{std::min({A.x, B.x, C.x}), std::min({A.y, B.y, C.y}), std::max({A.x, B.x, C.x}),
                   std::max({A.y, B.y, C.y})};
      clip_to(piece_, rect, tb, A, B, C, object);
      if (!join_.empty()) clip_to(join_, join, tb, A, B, C, object);
    }
  }

  // Clips `piece` (box `pb`) against the drawn triangle A, B, C (box `tb`) and emits the result.
  void clip_to(const Polygon& piece, const Box& pb, const Box& tb, const pm::Vec3& A, const pm::Vec3& B,
               const pm::Vec3& C, std::uint32_t object) {
    if (tb.x1 < pb.x0 || tb.x0 > pb.x1 || tb.y1 < pb.y0 || tb.y0 > pb.y1) return;
    ++stats.drawn_triangles_tested;
    const P2 a{A.x, A.y}, b{B.x, B.y}, c{C.x, C.y};
    const double det = cross(a, b, c);
    if (det == 0) return;  // vertical in plan: covers no ground
    const double sign = det > 0 ? 1.0 : -1.0;
    clip_half_plane(piece, a, b, sign, tmp_);
    if (tmp_.size() < 3) return;
    clip_half_plane(tmp_, b, c, sign, clip_);
    if (clip_.size() < 3) return;
    clip_half_plane(clip_, c, a, sign, tmp_);
    if (tmp_.size() >= 3) emit(tmp_, A, B, C, det, object);
  }

  // Fans the clipped polygon `p` (CCW in plan) into triangles lifted onto the plane of the drawn
  // triangle A, B, C (plan determinant det).
  void emit(const Polygon& p, const pm::Vec3& A, const pm::Vec3& B, const pm::Vec3& C, double det,
            std::uint32_t object) {
    fan_.clear();
    for (std::size_t k = 1; k + 1 < p.size(); ++k)
      if (cross(p[0], p[k], p[k + 1]) > 0) fan_.push_back(std::uint32_t(k));
    if (fan_.empty()) return;
    ++stats.clips;
    const pm::Vec3 e1 = pm::sub(B, A), e2 = pm::sub(C, A);
    pm::Vec3 nrm = pm::cross(e1, e2);
    const double len = std::sqrt(pm::dot(nrm, nrm)) * (nrm.z < 0 ? -1.0 : 1.0);
    nrm = {nrm.x / len, nrm.y / len, nrm.z / len};
    const auto base = std::uint32_t(out_.positions.size());
    for (const P2& q : p) {
      const double qx = q.x - A.x, qy = q.y - A.y;
      const double l1 = (qx * e2.y - qy * e2.x) / det, l2 = (e1.x * qy - e1.y * qx) / det;
      out_.positions.push_back({q.x, q.y, A.z + l1 * e1.z + l2 * e2.z});
      out_.normals.push_back(nrm);
    }
    for (const std::uint32_t k : fan_) {
      out_.triangles.push_back({base, base + k, base + k + 1});
      out_.triangle_object.push_back(object);
    }
    stats.triangles += fan_.size();
  }

  const TerrainRuntime& rt_;
  const DrawnMesh& mesh_;
  ObjectMesh& out_;
  std::vector<P2> points_;
  Polygon piece_, join_, clip_, tmp_;
  std::vector<std::uint32_t> ids_, fan_;
};

}  // namespace

DrapeStats drape_line(const TerrainRuntime& rt, std::span<const WorldPoint> line, double width_m,
                      std::uint32_t object, ObjectMesh& out) {
  const DrapedLine one{line, width_m, object};
  return drape_lines(rt, std::span<const DrapedLine>(&one, 1), out);
}

DrapeStats drape_lines(const TerrainRuntime& rt, std::span<const DrapedLine> lines, ObjectMesh& out) {
  Draper d(rt, out);
  for (const DrapedLine& l : lines) d.line(l.points, l.width_m, l.object);
  return d.stats;
}

}  // namespace terralod::blocks
