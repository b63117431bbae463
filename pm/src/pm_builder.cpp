// The PM construction: greedy L-infinity half-edge collapses on a triangle mesh of the grid
// (Builder), run on vertical strips in parallel and then on their join (ProgressiveMesh::build).
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 2, Eq. 1. Each live vertex u
// keeps its best legal collapse u -> w (smallest error, then shortest edge) in an indexed
// queue (vertex_heap.hpp: a 4-ary heap over buckets), or a lower bound of it (then u is dirty
// and measured when the bound reaches the top). After collapsing u -> w, only vertices whose
// 1-ring changed (w and u's old neighbours) are re-evaluated; the rest of the mesh is
// untouched because vertices never move. A popped candidate is re-validated (the link
// condition may have changed through a neighbour) and re-evaluated when it became illegal.
// Legal: no new face flips in plan view, the link condition holds, and the boundary rule of
// grid_border.hpp (shared with ModLInfT) lets u move.
//
// Cost: one evaluation of u -> w rasterises the new 1-ring of w (about 3 N / m samples when
// the mesh has m of N vertices); evaluations stop as soon as they exceed the vertex's best
// candidate so far, and large triangles and long spokes are measured through small
// direct-mapped caches (cached_linf_error.hpp), since re-evaluating a vertex after one
// neighbour changed meets mostly the same ones again. Where a ring and the samples of its box
// share one height (sea, lakes), nothing is measured: its error is 0 (flat_box; SRTM's Kauai
// tile, 91 % sea, builds in 0.58x the time, the same blocks). Vertices are numbered in
// tile_order.hpp's order, so that the data a collapse touches lies close together, and the live
// elements are compacted as the mesh shrinks (compact). The mesh and its operations are
// collapse_mesh.hpp's.
// Where the time goes (N44W072 in blocks of 257, one thread, counted per strip): the first
// halving of the vertices (errors up to about 1 m) is half of the build and the second a
// quarter, the other 15 halvings the rest. In the first, a collapse costs 10.8 evaluations (5.6
// of its neighbours, 3.2 of popped lower bounds), 86 % of which stop at their cutoff and leave a
// lower bound. A build twice as fast has to evaluate less while errors are small, e.g. by
// collapsing independent local minima in sweeps of the grid, which would give up the exact order.
// Memory: OpenMesh connectivity (~180 bytes per vertex), every vertex's ring of halfedges (64
// bytes, CollapseMesh::Ring), queue entry, position and state (44 bytes per vertex), edge
// errors (8 bytes per edge), runs of equal heights (4 bytes per sample, flat_box); the large
// arrays (OpenMesh's included) on transparent huge pages where the OS allows it. Peak for the
// full N44W072 tile (two strips at once): 760 MB.
#include <algorithm>
#include <array>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "cached_linf_error.hpp"
#include "collapse_mesh.hpp"
#include "grid_mesh.hpp"
#include "huge_vector.hpp"
#include "strip_merge.hpp"
#include "terralod/pm/grid_border.hpp"
#include "terralod/pm/parallel.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "tile_order.hpp"
#include "vertex_heap.hpp"

namespace terralod::pm {
namespace {

using detail::CachedLInfError;
using detail::CollapseMesh;
using detail::HugeVector;
using detail::Mesh;
using detail::VertexHeap;

class Builder {
 public:
  // `flat`: equal_runs(hf).
  Builder(const Heightfield& hf, const BuildOptions& opt, const std::vector<std::uint32_t>& flat)
      : hf_(hf), opt_(opt), error_(hf, opt.metric), W_(hf.width()), H_(hf.height()), flat_(flat) {}

  // Shared progress of all builders of one build; only the reporting builder calls back, with
  // the largest fraction reached so far (a build made again whole reports from its start).
  struct Progress {
    std::atomic<std::size_t> done{0};
    std::atomic<bool> cancelled{false};
    std::size_t total = 1;
    double reported = 0.0;
  };

  // Full-resolution mesh of the cells whose column lies in [x0, x1). Vertices on a cut column
  // (x0 > 0 or x1 < W-1) are locked: the strip beside it shares them.
  void init_grid(int x0, int x1, std::vector<std::uint32_t>& dropped) {
    number_vertices(x0, x1);
    reserve_mesh(3 * std::size_t(x1 - x0 + 1) * H_, 2 * std::size_t(x1 - x0) * H_);
    std::vector<Mesh::VertexHandle> tri(3);
    const auto add_face = [&](const std::uint32_t(&)[3], const GridPoint(&corners)[3]) {
      for (int c = 0; c < 3; ++c)
        tri[c] = Mesh::VertexHandle(int(id_of_[id_index(corners[c].x, corners[c].y)]));
      return mesh_.add_triangle(tri).is_valid();
    };
    if (hf_.has_holes()) {
      // Around holes the faces OpenMesh accepts depend on the order they come in: row by row,
      // as the PM's full-resolution face numbering (dropped faces) expects (grid_mesh.hpp).
      detail::add_faces_row_by_row(hf_, x0, x1, add_face, dropped);
    } else {
      // Cells in tile order always extend the connected fans of their corners (see
      // tile_order.hpp): OpenMesh accepts every face. Cell (i,j) has its corner (i,j) first.
      for (std::uint32_t v = 0; v < n_ids_; ++v)
        if (point(v).x < x1 && point(v).y + 1 < H_)
          detail::add_cell_faces(hf_, point(v).x, point(v).y, add_face, dropped);
    }
    if (!hf_.has_holes()) grid_x0_ = x0, grid_x1_ = x1;
    for (int j = 0; j < H_; ++j) {
      if (x0 > 0) vs_[id_of_[id_index(x0, j)]].locked = 1;
      if (x1 < W_ - 1) vs_[id_of_[id_index(x1, j)]].locked = 1;
    }
    HugeVector<std::uint32_t>().swap(id_of_);  // needed no more
    edge_err_.assign(mesh_.n_edges(), 0.0);    // edges of the full-resolution grid lie on it
    mesh_.init_rings();
  }

  // A mesh given by its faces (CCW in (col,row)), e.g. the join of the strips; false when
  // OpenMesh refused one of them.
  bool init_faces(const std::vector<std::array<std::uint32_t, 3>>& faces) {
    std::vector<std::uint8_t> used(hf_.size(), 0);
    for (const auto& f : faces) used[f[0]] = used[f[1]] = used[f[2]] = 1;
    number_vertices(0, W_ - 1, &used);
    reserve_mesh(3 * faces.size() / 2 + 16, faces.size());
    std::vector<Mesh::VertexHandle> tri(3);
    for (const auto& f : faces) {
      for (int c = 0; c < 3; ++c) tri[c] = Mesh::VertexHandle(int(id_of_[f[c]]));  // all columns: the sample
      if (!mesh_.add_triangle(tri).is_valid()) return false;
    }
    HugeVector<std::uint32_t>().swap(id_of_);
    edge_err_.assign(mesh_.n_edges(), 0.0);
    mesh_.init_rings();
    if (error_.exact().metric() == ErrorMetric::Continuous)
      for (auto e : mesh_.edges()) {
        const auto h = mesh_.halfedge_handle(e, 0);
        edge_err_[e.idx()] = error_.exact().segment(point(std::uint32_t(mesh_.from_vertex_handle(h).idx())),
                                                    point(std::uint32_t(mesh_.to_vertex_handle(h).idx())));
      }
    return true;
  }

  std::size_t live_vertices() const {
    std::size_t live = 0;
    for (auto v : mesh_.vertices())
      if (!mesh_.status(v).deleted() && !mesh_.is_isolated(v)) ++live;
    return live;
  }

  // Greedy collapses until nothing can collapse, the next error exceeds max_error, or only
  // stop_live vertices are left.
  void run(std::vector<Collapse>& collapses, double quantum, std::size_t stop_live, Progress& progress,
           bool report) {
    std::size_t live = live_vertices();
    for (std::uint32_t v = 0; v < n_ids_; ++v)
      if (mesh_.ring(v).n > 0 && !grid_bound(v)) evaluate(v, /*exact=*/false);
    std::size_t since_report = 0;
    while (!heap_.empty() && live > stop_live) {
      const std::uint32_t u = heap_.top();
      const double e = heap_.top_error();
      if (e > opt_.max_error) break;
      // The top is at a random place of the mesh, and so is the next one: start loading the
      // first links of its chain of dependent loads while u is processed.
      prefetch_vertex(heap_.second());
      if (vs_[u].dirty) {
        // Its key was a lower bound: measure it, but only as far as the largest key of the
        // top's children. Measuring in full wastes work on vertices that will change again
        // before they could collapse; stopping at the next key (the smallest child) makes
        // vertices bounce back many times. Counted on a 241 x 241 crop (instructions of the
        // whole run): next key 4.11 G, largest child 3.82 G, largest grandchild 3.83 G,
        // next key then in full 4.11 G, in full 4.86 G.
        evaluate(u, /*exact=*/true, heap_.children_max_error());
        continue;
      }
      const std::uint32_t w = vs_[u].target;
      [[maybe_unused]] const auto vu = Mesh::VertexHandle(int(u));
      // One walk around u gives the halfedge to w, the ring for the link test, and what the
      // collapse moves. u's ring is the one it was measured with (any change to it makes u
      // dirty), so w is still a neighbour and the plan-view test still holds; but w's ring
      // may have changed since, so the link condition is tested again.
      neighbours_.clear();
      moved_.clear();
      Mesh::HalfedgeHandle h;
      mesh_.for_each_ring(u, [&](Mesh::HalfedgeHandle g) {
        const std::uint32_t x = std::uint32_t(mesh_.to_vertex_handle(g).idx());
        if (x == w) h = g;
        neighbours_.push_back(x);
        moved_.push_back(g);
      });
      assert(h.is_valid() && geometry_ok(vu, w));
      if (!mesh_.link_ok(h, neighbours_)) {
        evaluate(u, /*exact=*/true);  // a change around w made the candidate illegal
        continue;
      }
      mesh_.collapse_halfedge(h, moved_);
      heap_.remove(u);
      --live;
      ++collapsed_;
      if (error_.exact().metric() == ErrorMetric::Continuous) update_edge_errors(w);
      collapses.push_back(
          Collapse{sample_at(point(u)), sample_at(point(w)), std::ceil(e / quantum) * quantum});
      // The neighbours are measured now, while their rings are in cache, and as far as the
      // keys at the top of the heap (like a popped vertex, see above): most are found to lie
      // above them, and wait with that tighter lower bound instead of being measured again,
      // from cold memory, when a looser bound (ring edges and the error at u only) reaches
      // the top. Instructions on the 241 x 241 crop: 3.82 G -> 3.52 G (cutoff 0: 3.88 G,
      // twice the largest child key: 4.37 G).
      // Not measuring them at all (marking them dirty under their old keys, which are then no
      // lower bounds) saves most of this work but lets a neighbour whose error fell wait past
      // its turn. Measured on N44W072 (`terralod build --threads 1`, 4 alternating pairs, and
      // the 1025 x 1025 crop of terralod-bench-pm): every neighbour deferred, 0.73 x the build
      // time for 0.3 / 1.0 / 2.8 / 5.3 / 2.6 % more triangles at 0.5 / 1 / 2 / 5 / 50 m and
      // 6.9 % more bytes a vertex; only those not aimed at u or w, 0.82 x for 0.2 / 0.8 / 1.9 /
      // 2.8 / 1.0 %; only those keyed above 3 x e, the same triangles and 0.99 x. The build is
      // paid once and the triangles every frame, so the order stays exact.
      for (std::uint32_t n : neighbours_) prefetch_vertex(n);
      for (std::uint32_t n : neighbours_) mesh_.prefetch_ring(n);
      for (std::uint32_t n : neighbours_) prefetch_ring_data(n);
      for (std::uint32_t n : neighbours_) evaluate(n, /*exact=*/true, heap_.children_max_error());
      if (collapsed_ * kCompactAt >= n_ids_) compact();
      if (++since_report == 4096) {
        const std::size_t done = progress.done.fetch_add(since_report) + since_report;
        since_report = 0;
        if (progress.cancelled) throw std::runtime_error("progressive mesh build cancelled");
        if (report)
          progress.reported =
              std::max(progress.reported, std::min(1.0, double(done) / double(progress.total)));
        if (report && opt_.progress && !opt_.progress(progress.reported)) {
          progress.cancelled = true;
          throw std::runtime_error("progressive mesh build cancelled");
        }
      }
    }
    progress.done += since_report;
  }

 private:
  // Integer division by the grid width is slow in the inner loops, so points are tabulated.
  GridPoint point(std::uint32_t v) const { return sites_[v].p; }
  std::uint32_t sample_at(GridPoint p) const {
    return std::uint32_t(p.y) * std::uint32_t(W_) + std::uint32_t(p.x);
  }

  // Vertex ids follow tile_order() over the columns [x0, x1]; samples outside them, or not in
  // `used` when given, get no id, so that every per-vertex array (OpenMesh's included) holds
  // only the vertices this builder works on. Cells are created in the same order, so a ring's
  // halfedges are close too.
  void number_vertices(int x0, int x1, const std::vector<std::uint8_t>* used = nullptr) {
    const std::vector<std::uint32_t> sample_of = detail::tile_order(x0, x1, W_, H_, used);
    n_ids_ = std::uint32_t(sample_of.size());
    id_x0_ = x0, id_cols_ = std::size_t(x1 + 1 - x0);
    id_of_.assign(id_cols_ * std::size_t(H_), UINT32_MAX);
    vs_.assign(n_ids_, VertexState{});
    sites_.assign(n_ids_, Site{});
    for (std::uint32_t v = 0; v < n_ids_; ++v) {
      const std::uint32_t s = sample_of[v];
      sites_[v].p = GridPoint{int(s % std::uint32_t(W_)), int(s / std::uint32_t(W_))};
      id_of_[id_index(sites_[v].p.x, sites_[v].p.y)] = v;
      sites_[v].z = hf_[s];
    }
    heap_.reset(n_ids_, &vs_.data()->heap_pos, &vs_.data()->bucket,
                sizeof(VertexState) / sizeof(std::uint32_t));
  }

  void reserve_mesh(std::size_t n_edges, std::size_t n_faces) {
    mesh_.init_vertices(n_ids_, n_edges, n_faces);
    error_.reset();
  }

  // After a collapse, the neighbours' rings are read one after the other by evaluate(); this
  // starts, after CollapseMesh::prefetch_ring, the loads of what evaluate() reads through them
  // (ring vertices' records, the crossing errors of ring edges).
  void prefetch_ring_data(std::uint32_t v) const {
    const CollapseMesh::Ring& r = mesh_.ring(v);
    const std::uint32_t n = std::min(r.n, CollapseMesh::kRingCap);
    for (std::uint32_t i = 0; i < n; ++i) {
      const auto h = Mesh::HalfedgeHandle(int(r.h[i]));
      __builtin_prefetch(&sites_[std::uint32_t(mesh_.to_vertex_handle(h).idx())]);
      __builtin_prefetch(&edge_err_[std::uint32_t(mesh_.next_halfedge_handle(h).idx()) >> 1]);
    }
  }

  // Collapses leave their deleted vertices, edges and faces in every array, so the live data
  // of a region thins out (CollapseMesh::compact). Once 1/kCompactAt of the vertices are
  // deleted, compact() moves the live elements down in place, keeping their order: every
  // tie-break by vertex id, every ring's order and the heap's order stay, so the PM is the same
  // as without it (the caches are keyed by sample, not by id). Each pass costs a sequential
  // sweep of the arrays; every quarter of the vertices (rather than every half) measured 0.96x
  // the build time (full tile, 14 alternating pairs).
  static constexpr std::size_t kCompactAt = 4;
  void compact() {
    mesh_.compact(
        [&](std::uint32_t v, std::uint32_t to) {
          VertexState& sv = vs_[to];
          sv = vs_[v];
          sites_[to] = sites_[v];
          if (sv.target != UINT32_MAX)
            sv.target = mesh_.new_vertex_id(sv.target);  // a deleted target is never used again
        },
        [&](std::uint32_t e, std::uint32_t to) { edge_err_[to] = edge_err_[e]; });
    const std::uint32_t lv = std::uint32_t(mesh_.n_vertices());
    vs_.resize(lv);
    sites_.resize(lv);
    edge_err_.resize(mesh_.n_edges());
    heap_.renumber(mesh_.new_vertex_ids());
    n_ids_ = lv;
    collapsed_ = 0;
  }

  // Starts loading the per-vertex data that evaluate(v) and the heap read first.
  void prefetch_vertex(std::uint32_t v) const {
    if (v == UINT32_MAX) return;
    __builtin_prefetch(&mesh_.ring(v));
    __builtin_prefetch(&vs_[v]);
    __builtin_prefetch(&sites_[v]);
  }

  // Crossing errors of the edges u's collapse into w moved to w (moved_: u's outgoing
  // halfedges before the collapse); the others around w kept their segments (see
  // CollapseMesh::collapse_halfedge).
  void update_edge_errors(std::uint32_t w) {
    for (const auto g : moved_) {
      const auto e = mesh_.edge_handle(g);
      if (mesh_.status(e).deleted()) continue;
      edge_err_[e.idx()] = spoke_error(w, std::uint32_t(mesh_.to_vertex_handle(g).idx()), 1e300);
    }
  }

  // Crossing error of the segment (w, x), measured from the endpoint with the smaller vertex id.
  double spoke_error(std::uint32_t w, std::uint32_t x, double cutoff) {
    const GridPoint a = point(w), b = point(x);
    if (sites_[x].z == sites_[w].z &&
        flat_box(std::min(a.x, b.x), std::min(a.y, b.y), std::max(a.x, b.x), std::max(a.y, b.y), sites_[w].z))
      return 0.0;
    return error_.segment(point(std::min(w, x)), point(std::max(w, x)), cutoff);
  }

  // Whether every sample of the box [x0, x1] x [y0, y1] is valid with the height z: then every
  // triangle and segment of samples at height z inside it lies on the terrain, with error 0, and
  // need not be measured. Oceans and lakes are flat (91 % of SRTM's Kauai tile is sea at 0 m),
  // and a flat region was measured sample by sample like a rugged one: no cutoff ever stops a
  // measurement of 0. One look per row, through the runs of equal samples (flat_).
  bool flat_box(int x0, int y0, int x1, int y1, double z) const {
    const double* zs = hf_.samples().data();
    const std::uint32_t need = std::uint32_t(x1 - x0 + 1);
    for (int y = y0; y <= y1; ++y) {
      const std::size_t i = std::size_t(y) * std::size_t(W_) + std::size_t(x0);
      if (zs[i] != z || flat_[i] < need) return false;
    }
    return true;
  }

  // Plan-view legality of u -> w: every face around u that does not contain w stays CCW.
  bool geometry_ok(Mesh::VertexHandle vu, std::uint32_t w) const {
    const GridPoint pw = point(w);
    bool ok = true;
    mesh_.for_each_outgoing(vu, [&](Mesh::HalfedgeHandle h) {
      if (mesh_.is_boundary(h)) return;
      const auto hn = mesh_.next_halfedge_handle(h);
      const std::uint32_t a = std::uint32_t(mesh_.to_vertex_handle(h).idx());
      const std::uint32_t b = std::uint32_t(mesh_.to_vertex_handle(hn).idx());
      if (a != w && b != w && orient2d(pw, point(a), point(b)) <= 0) ok = false;
    });
    return ok;
  }

  double cached_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, double cutoff) {
    return error_.samples_in_triangle(point(a), point(b), point(c), cutoff);
  }

  // evaluate(v, exact = false) for a vertex inside the hole-free grid of init_grid, from the
  // heights alone: its ring is the hexagon of the grid's triangulation (neighbours at +-(1,0),
  // +-(0,1), +-(1,1)), every candidate is legal, the ring edges lie on the surface, and v lies
  // midway between a candidate w and the ring vertex opposite w, so the bound of v -> w is
  // |z(w) + z(opposite) - 2 z(v)| / 2: the same operations, in the same order, as evaluate()'s
  // for that face, and so the same key (the target of a lower bound is never used). Walking
  // 720k rings for this was a tenth of a strip's build. Returns false for other vertices.
  bool grid_bound(std::uint32_t v) {
    VertexState& s = vs_[v];
    const GridPoint p = point(v);
    if (grid_x0_ < 0 || p.x <= grid_x0_ || p.x >= grid_x1_ || p.y <= 0 || p.y >= H_ - 1) return false;
    const std::size_t i = std::size_t(p.y) * std::size_t(W_) + std::size_t(p.x), w = std::size_t(W_);
    const double* z = hf_.samples().data();
    const double zu = z[i];
    const auto bound = [&](std::size_t d) {
      return std::max(0.0, std::abs((z[i + d] + z[i - d]) - 2.0 * zu) / 2.0);
    };
    double lb = bound(1);
    std::uint32_t tie = 1;
    lb = std::min(lb, bound(w));
    if (const double diagonal = bound(w + 1); diagonal < lb) lb = diagonal, tie = 2;
    s.dirty = 1;
    s.target = UINT32_MAX;
    heap_.set(v, lb, tie);
    return true;
  }

  // Files u in the heap with its best legal collapse. With exact = false (the first pass over
  // all vertices) the key is only a lower bound of that collapse's error: u is marked dirty and
  // measured exactly when the bound reaches the top of the heap. Measurements that exceed
  // `cutoff` also leave a lower bound. Since a lower bound never delays a vertex, the order of
  // collapses is the same as with exact keys, at a fraction of the cost.
  void evaluate(std::uint32_t u, bool exact, double cutoff = 1e300) {
    VertexState& su = vs_[u];
    const GridPoint pu = point(u);
    su.dirty = 0;
    if (su.locked || mesh_.ring(u).n == 0) {
      heap_.remove(u);
      return;
    }
    // One walk around u: its ring vertices in order (ringv_[k] = head of the k-th outgoing
    // halfedge), their positions relative to u and heights, and the faces (u, ringv_[k],
    // ringv_[k-1]) that exist, with the crossing error of their edge opposite u.
    const bool continuous = error_.exact().metric() == ErrorMetric::Continuous;
    ringv_.clear();
    ringh_.clear();
    ring_.clear();
    rloc_.clear();
    std::uint32_t gaps = 0;  // outgoing boundary halfedges: stretches of boundary through u
    {
      std::uint32_t k = 0;
      mesh_.for_each_ring(u, [&](Mesh::HalfedgeHandle h) {
        const std::uint32_t a = std::uint32_t(mesh_.to_vertex_handle(h).idx());
        ringv_.push_back(a);
        ringh_.push_back(h);
        // Records are filled field by field in place: a record built aside and copied in is
        // read back in wider loads than its fields were written with, which stalls the CPU
        // (store forwarding fails) on every ring vertex.
        const Site& sa = sites_[a];
        Local& la = rloc_.emplace_back();
        la.x = std::int64_t(sa.p.x) - pu.x, la.y = std::int64_t(sa.p.y) - pu.y, la.z = sa.z;
        if (mesh_.is_boundary(h)) {
          ++gaps;
        } else {
          // The face's third corner is the previous ring vertex (filled in below, so that
          // the head of next(h) need not be loaded); its edge error is at next(h)'s edge.
          RingFace& f = ring_.emplace_back();
          f.a = a, f.ka = k;
          f.edge_error = continuous ? edge_err_[mesh_.edge_handle(mesh_.next_halfedge_handle(h)).idx()] : 0.0;
        }
        ++k;
      });
    }
    heap_.prefetch_entry(u);  // read by the heap_.set() at the end
    const std::uint32_t n = std::uint32_t(ringv_.size());
    const Local* rl = rloc_.data();
    // Face j joins ring indices ka and kb = ka - 1 (mod n); face_at_[k]: the face at k exists.
    face_at_.assign(n, 0);
    double ring_edges = 0.0;
    for (RingFace& f : ring_) {
      f.kb = f.ka == 0 ? n - 1 : f.ka - 1;
      f.b = ringv_[f.kb];
      f.cross = rl[f.ka].x * rl[f.kb].y - rl[f.ka].y * rl[f.kb].x;
      face_at_[f.ka] = 1;
      ring_edges = std::max(ring_edges, f.edge_error);
    }
    // Candidate targets, as ring indices.
    cand_.clear();
    if (gaps > 0) {
      // Only into a boundary neighbour, where the boundary is straight through u
      // (grid_border.hpp). With one stretch of boundary through u, its outgoing halfedge is its
      // boundary one: ringv_[0] is the next boundary vertex and ringv_[n-1] the previous one.
      const std::uint32_t next = ringv_[0], prev = ringv_[n - 1];
      if (gaps == 1 && boundary_straight_at(point(prev), pu, point(next))) {
        cand_.push_back({next, 0, 0, 0});
        cand_.push_back({prev, 0, 0, n - 1});
      }
    } else {
      for (std::uint32_t k = 0; k < n; ++k) cand_.push_back({ringv_[k], 0, 0, k});
    }
    // Lower bound of each candidate: the error at u itself, at the new spokes and at the ring
    // edges, all of which are points of the new 1-ring. Every edge of u's ring survives as an
    // edge of the new 1-ring of w, including the two that end at w, so all count. Whether a
    // candidate is legal (no new face flips, fan_ok) is asked only of those that could win,
    // in order of their bounds: testing every candidate against every face was the build's
    // innermost loop.
    const std::size_t nf = ring_.size();
    const RingFace* fs = ring_.data();
    std::size_t kept = 0;
    const double zu = sites_[u].z;
    for (std::size_t i = 0; i < cand_.size(); ++i) {
      const std::uint32_t cw = cand_[i].w, ck = cand_[i].k;
      const Local& lw = rl[ck];
      // With positions relative to u: orient(w, a, b) = cross(a, b) + X(a) - X(b), where
      // X(x) = cross(w, x); orient(w, a, u) = X(a) and orient(b, w, u) = -X(b). u lies in
      // the first new triangle (w, a, b) whose wedge at w contains the direction w -> u:
      // orient(w, a, u) >= 0 and orient(w, u, b) >= 0.
      double lb = ring_edges;
      bool flat = false;
      for (std::size_t j = 0; j < nf; ++j) {
        const RingFace& f = fs[j];
        if (f.ka == ck || f.kb == ck) continue;
        const std::int64_t xa = lw.x * rl[f.ka].y - lw.y * rl[f.ka].x,
                           xb = lw.x * rl[f.kb].y - lw.y * rl[f.kb].x;
        const std::int64_t e2 = xa, e1 = -xb;
        if (e2 >= 0 && e1 >= 0) {
          const std::int64_t area2 = f.cross + xa - xb;
          if (area2 <= 0) {  // the face would flip: illegal
            flat = true;
            break;
          }
          const std::int64_t e0 = area2 - e1 - e2;  // barycentric weights sum to area2
          const double num = double(e0) * lw.z + double(e1) * rl[f.ka].z + double(e2) * rl[f.kb].z;
          lb = std::max(lb, std::abs(num - double(area2) * zu) / double(area2));
          break;
        }
      }
      if (flat) continue;
      Candidate& c = cand_[kept++];  // in place, field by field (see the ring walk above)
      c.w = cw, c.k = ck, c.lower = lb, c.tie = tie_of(pu, point(cw));
    }
    cand_.resize(kept);
    const auto by_bound = [](const Candidate& a, const Candidate& b) {
      return a.lower < b.lower || (a.lower == b.lower && a.tie < b.tie);
    };
    // Insertion sort (stable, no allocation; rings are short).
    const auto sort_by_bound = [&] {
      for (std::size_t i = 1; i < cand_.size(); ++i)
        for (std::size_t j = i; j > 0 && by_bound(cand_[j], cand_[j - 1]); --j)
          std::swap(cand_[j], cand_[j - 1]);
    };
    if (!exact) {  // only the smallest bound of a legal candidate is needed
      const Candidate* pick = nullptr;
      if (!cand_.empty()) {  // usually the smallest bound is legal: no sort then
        const Candidate& c = *std::min_element(cand_.begin(), cand_.end(), by_bound);
        if (fan_ok(c.k)) pick = &c;
      }
      if (!pick) {
        sort_by_bound();
        for (const Candidate& c : cand_)
          if (fan_ok(c.k)) {
            pick = &c;
            break;
          }
      }
      if (!pick) {
        heap_.remove(u);
        return;
      }
      su.dirty = 1;
      su.target = pick->w;
      heap_.set(u, pick->lower, pick->tie);
      return;
    }
    sort_by_bound();
    // A ring whose vertices and the samples of whose bounding box all lie at u's height: every
    // candidate's new triangles and spokes lie on the terrain, so its error is its lower bound
    // (0, up to the rounding of the bound's own interpolation).
    bool flat = true;
    int bx0 = pu.x, by0 = pu.y, bx1 = pu.x, by1 = pu.y;
    for (std::uint32_t k = 0; flat && k < n; ++k) {
      flat = rl[k].z == zu;
      bx0 = std::min(bx0, int(pu.x + rl[k].x)), bx1 = std::max(bx1, int(pu.x + rl[k].x));
      by0 = std::min(by0, int(pu.y + rl[k].y)), by1 = std::max(by1, int(pu.y + rl[k].y));
    }
    flat = flat && flat_box(bx0, by0, bx1, by1, zu);
    // Exact errors in order of their lower bounds, skipping candidates that cannot win.
    // Measurements stop at `cutoff` (see run()): when every candidate exceeds
    // it, the values reached are a better lower bound and u goes back, still dirty.
    double best = 1e300;
    std::uint32_t best_tie = UINT32_MAX;
    std::uint32_t best_w = UINT32_MAX;
    double partial = 1e300;
    std::uint32_t partial_tie = 0;
    std::uint32_t partial_w = UINT32_MAX;
    for (const Candidate& c : cand_) {
      if (c.lower > best || (c.lower == best && c.tie >= best_tie)) break;
      if (best_w == UINT32_MAX && c.lower > partial) break;
      if (!fan_ok(c.k)) continue;
      const double limit = std::min(best, cutoff);
      double e = c.lower;
      if (continuous && !flat)  // the new spokes (w, x) to ring vertices x not already joined to w
        for (std::uint32_t k = 0; k < n; ++k) {
          // (w, x) is an edge of u's ring when x is w's ring neighbour across an existing face.
          const std::uint32_t kn = c.k + 1 == n ? 0 : c.k + 1, kp = c.k == 0 ? n - 1 : c.k - 1;
          if (k == c.k || (k == kn && face_at_[kn]) || (k == kp && face_at_[c.k])) continue;
          e = std::max(e, spoke_error(c.w, ringv_[k], limit));
          if (e > limit) break;
        }
      if (e <= limit && !flat)
        for (const RingFace& f : ring_) {
          if (f.a == c.w || f.b == c.w) continue;
          e = std::max(e, cached_triangle(c.w, f.a, f.b, limit));
          if (e > limit) break;
        }
      if (e > cutoff) {  // a lower bound only
        if (e < partial) partial = e, partial_tie = c.tie, partial_w = c.w;
        continue;
      }
      if (!(e < best || (e == best && c.tie < best_tie))) continue;
      // The topological test is the dearest, so it runs only for a candidate that would win.
      if (!mesh_.link_ok(ringh_[c.k], ringv_)) continue;
      best = e, best_tie = c.tie, best_w = c.w;
    }
    if (best_w == UINT32_MAX && partial_w != UINT32_MAX) {
      su.dirty = 1;
      su.target = partial_w;
      heap_.set(u, partial, partial_tie);
      return;
    }
    if (best_w == UINT32_MAX) {
      heap_.remove(u);
      return;
    }
    su.target = best_w;
    heap_.set(u, best, best_tie);
  }

  // Whether collapsing u into its ring vertex k leaves every new face (w, a, b)
  // counter-clockwise (ring_ and rloc_ as evaluate() filled them).
  bool fan_ok(std::uint32_t k) const {
    const Local& lw = rloc_[k];
    for (const RingFace& f : ring_) {
      if (f.ka == k || f.kb == k) continue;
      const Local &la = rloc_[f.ka], &lb = rloc_[f.kb];
      if (f.cross + (lw.x * la.y - lw.y * la.x) - (lw.x * lb.y - lw.y * lb.x) <= 0) return false;
    }
    return true;
  }

  // Tie-break of equal errors: the squared length of the collapsed edge, saturated (exact
  // below 46341 samples per side, where every order below is the one of the exact length).
  static std::uint32_t tie_of(GridPoint a, GridPoint b) {
    const std::uint64_t dx = std::uint64_t(std::abs(std::int64_t(a.x) - b.x)),
                        dy = std::uint64_t(std::abs(std::int64_t(a.y) - b.y));
    return std::uint32_t(std::min<std::uint64_t>(dx * dx + dy * dy, UINT32_MAX));
  }

  const Heightfield& hf_;
  const BuildOptions& opt_;
  CachedLInfError error_;
  int W_, H_;
  CollapseMesh mesh_;
  // What the loop reads of a vertex besides OpenMesh's record and its ring, in two arrays:
  // where it is (read for every ring vertex of an evaluated vertex: a dense 16-byte record),
  // and its state (read and written for the evaluated vertex and by the heap).
  struct Site {
    GridPoint p;  // grid position
    double z;     // height
  };
  static_assert(sizeof(Site) == 16);
  HugeVector<Site> sites_;  // by vertex id (see number_vertices)
  struct VertexState {
    std::uint32_t heap_pos;             // owned by heap_
    std::uint32_t target = UINT32_MAX;  // best collapse target (a lower-bound one when dirty)
    std::uint8_t dirty = 0;             // the heap key is a lower bound
    std::uint8_t locked = 0;            // on a cut column shared with another strip
    std::uint16_t bucket;               // owned by heap_
  };
  static_assert(sizeof(VertexState) == 12);
  HugeVector<VertexState> vs_;  // by vertex id (see number_vertices)
  VertexHeap heap_;
  struct Candidate {
    std::uint32_t w;
    double lower;
    std::uint32_t tie;
    std::uint32_t k;  // index of w in ringv_
  };
  struct Local {
    std::int64_t x, y;  // position relative to the evaluated vertex
    double z;
  };
  std::vector<Local> rloc_;
  std::vector<std::uint8_t> face_at_;
  std::vector<std::uint32_t> neighbours_, ringv_;
  std::vector<Mesh::HalfedgeHandle> moved_;  // u's outgoing halfedges before its collapse
  std::vector<Mesh::HalfedgeHandle> ringh_;  // evaluate(): u's outgoing halfedges, by ring index
  // While the mesh is made: vertex id of sample (i, j) at id_of_[id_index(i, j)], over the
  // builder's columns only.
  HugeVector<std::uint32_t> id_of_;
  int id_x0_ = 0;
  std::size_t id_cols_ = 0;
  std::size_t id_index(int i, int j) const { return std::size_t(j) * id_cols_ + std::size_t(i - id_x0_); }
  std::uint32_t n_ids_ = 0;          // vertex ids are 0 .. n_ids_ - 1 (see number_vertices, compact)
  int grid_x0_ = -1, grid_x1_ = -1;  // init_grid's columns when the grid has no holes
  std::size_t collapsed_ = 0;        // collapses since the last compact()
  std::vector<Candidate> cand_;

  struct RingFace {        // the face (u, a, b) of u's ring
    std::uint32_t a, b;    // vertex ids
    std::uint32_t ka, kb;  // their ring indices: kb = ka - 1 (mod n)
    std::int64_t cross;    // cross(a - u, b - u), twice the face's area
    double edge_error;     // crossing error of the edge (a, b)
  };
  std::vector<RingFace> ring_;
  HugeVector<double> edge_err_;
  // flat_[s]: how many valid samples from s rightwards along its row have its height (see flat_box).
  const std::vector<std::uint32_t>& flat_;
};

// The runs of valid samples of equal height along the rows of hf (Builder's flat_; 0 at a hole).
std::vector<std::uint32_t> equal_runs(const Heightfield& hf) {
  const std::size_t W = std::size_t(hf.width());
  const double* z = hf.samples().data();
  std::vector<std::uint32_t> run(hf.size());
  for (std::size_t row = 0; row < hf.size(); row += W)
    for (std::size_t x = W; x-- > 0;) {
      const std::size_t i = row + x;
      run[i] = !hf.valid(i) ? 0 : x + 1 < W && z[i + 1] == z[i] && run[i + 1] > 0 ? run[i + 1] + 1 : 1;
    }
  return run;
}

}  // namespace

ProgressiveMesh ProgressiveMesh::build(const Heightfield& hf, const BuildOptions& options) {
  detail::check_buildable(hf);
  const double quantum = error_quantum_for(hf);
  std::vector<Collapse> collapses;
  collapses.reserve(hf.size());
  std::vector<std::uint32_t> dropped;
  Builder::Progress progress;
  const std::vector<std::uint32_t> flat = equal_runs(hf);
  std::size_t valid = 0;
  for (std::size_t i = 0; i < hf.size(); ++i) valid += hf.valid(i);
  progress.total = valid > 4 ? valid - 4 : 1;

  // The number of strips depends on the grid only, never on the machine, so that the same
  // heightfield always gives the same PM; threads only decide how many strips run at once.
  // Two strips: this machine kind has two cores, and every cut column stays at full
  // resolution below the join error, so more cuts cost triangles at fine levels.
  const int strips = (options.parallel_strips && hf.width() - 1 >= 256 && hf.size() >= (1u << 16)) ? 2 : 1;
  const int threads = std::max(
      1, std::min(strips, options.threads > 0 ? options.threads
                                              : int(std::max(1u, std::thread::hardware_concurrency()))));
  const auto build_whole = [&] {
    Builder b(hf, options, flat);
    b.init_grid(0, hf.width() - 1, dropped);
    b.run(collapses, quantum, 0, progress, /*report=*/true);
  };
  if (strips == 1) {
    build_whole();
  } else {
    // Phase 1: vertical strips sharing their cut columns (locked), decimated in parallel
    // until each keeps 1/kStripKeep of its vertices. The join below runs on one thread, so
    // the strips go far: a smaller join costs only a higher common error, below which the cut
    // column stays at full resolution (about 2 triangles per row, at coarse levels only). Their
    // sequences are merged by strip_merge.hpp.
    constexpr std::size_t kStripKeep = 128;
    std::vector<int> cuts(strips + 1);
    for (int t = 0; t <= strips; ++t) cuts[t] = int(std::int64_t(hf.width() - 1) * t / strips);
    std::vector<std::vector<Collapse>> seq(strips);
    std::vector<std::vector<std::uint32_t>> drop(strips);
    std::vector<std::exception_ptr> failure(strips);
    auto strip = [&](int t) {
      try {
        Builder b(hf, options, flat);
        b.init_grid(cuts[t], cuts[t + 1], drop[t]);
        const std::size_t live = b.live_vertices();
        seq[t].reserve(live);  // one allocation: growing it costs copies and page faults
        b.run(seq[t], quantum, live / kStripKeep, progress, /*report=*/t == 0);
      } catch (...) {
        failure[t] = std::current_exception();
        progress.cancelled = true;
      }
    };
    parallel_for(std::size_t(strips), threads, [&](std::size_t t) { strip(int(t)); });
    for (auto& f : failure)
      if (f) std::rethrow_exception(f);
    detail::merge_strips(seq, collapses);
    seq.clear();
    for (auto& d : drop) dropped.insert(dropped.end(), d.begin(), d.end());
    std::sort(dropped.begin(), dropped.end());
    // Phase 2: the joined mesh (the image of the full-resolution faces under the collapses
    // so far) continues on one thread.
    ProgressiveMesh partial = from_parts(hf, options.metric, quantum, collapses, dropped);
    TriangleMesh joined = partial.extract_after(collapses.size());
    std::vector<std::array<std::uint32_t, 3>> faces(joined.triangles.size());
    for (std::size_t f = 0; f < faces.size(); ++f)
      for (int c = 0; c < 3; ++c) faces[f][c] = joined.vertices[joined.triangles[f][c]];
    progress.done = collapses.size();
    Builder b(hf, options, flat);
    if (b.init_faces(faces)) {
      b.run(collapses, quantum, 0, progress, /*report=*/true);
    } else {
      // With holes, the union of two manifold strips can pinch at a cut vertex (two fans of
      // faces that touch only there), which OpenMesh may refuse in the order the faces come
      // in: such a grid is built whole, as every grid with holes was before.
      if (!hf.has_holes()) throw std::logic_error("progressive mesh: joined strips are not manifold");
      collapses.clear();
      dropped.clear();
      progress.done = 0;
      build_whole();
    }
  }
  if (options.progress) options.progress(1.0);
  return from_parts(hf, options.metric, quantum, std::move(collapses), std::move(dropped));
}

}  // namespace terralod::pm
