// The PM construction loop: greedy L-infinity half-edge collapses on an OpenMesh triangle mesh.
//
// Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 2, Eq. 1. Each live vertex u
// keeps its best legal collapse u -> w (smallest error, then shortest edge) in an indexed
// queue (VertexHeap: a 4-ary heap over buckets), or a lower bound of it (then u is dirty and
// measured when the bound reaches the top). After collapsing u -> w, only vertices whose
// 1-ring changed (w and u's old
// neighbours) are re-evaluated; the rest of the mesh is untouched because vertices never
// move. A popped candidate is re-validated (the link condition may have changed through a
// neighbour) and re-evaluated when it became illegal. The grid border rules are
// grid_border.hpp's, shared with ModLInfT.
//
// Cost: one evaluation of u -> w rasterises the new 1-ring of w (about 3 N / m samples when
// the mesh has m of N vertices); evaluations stop as soon as they exceed the vertex's best
// candidate so far, and the error of each large triangle (256 cells and more) is cached in a
// small direct-mapped table keyed by its corners, since re-evaluating a vertex after one
// neighbour changed meets mostly the same triangles again; long spokes likewise in a 512 KiB
// table. Vertices are numbered in tiles with Z-order inside (number_vertices), so that the
// data a collapse touches lies close together, and the live elements are compacted as the mesh
// shrinks (compact). Memory: OpenMesh connectivity (~180 bytes per vertex), every vertex's
// ring of halfedges (64 bytes, see Ring), queue entry, position and state (44 bytes per
// vertex), edge errors (8 bytes per edge); the large arrays (OpenMesh's included) on
// transparent huge pages where the OS allows it. Peak for the full N44W072 tile (two strips at
// once): 760 MB.
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>
#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "huge_vector.hpp"
#include "terralod/pm/grid_border.hpp"
#include "terralod/pm/parallel.hpp"
#include "terralod/pm/progressive_mesh.hpp"
#include "triangle_cache.hpp"
#include "vertex_heap.hpp"

namespace terralod::pm {
namespace {

using detail::HugeVector;
using detail::TriangleCache;
using detail::VertexHeap;

struct MeshTraits : OpenMesh::DefaultTraits {
  VertexAttributes(OpenMesh::Attributes::Status);
  EdgeAttributes(OpenMesh::Attributes::Status);
  FaceAttributes(OpenMesh::Attributes::Status);
  HalfedgeAttributes(OpenMesh::Attributes::PrevHalfedge);
};
using Mesh = OpenMesh::TriMesh_ArrayKernelT<MeshTraits>;

class Builder {
 public:
  Builder(const Heightfield& hf, const BuildOptions& opt)
      : hf_(hf), opt_(opt), err_(hf, opt.metric), W_(hf.width()), H_(hf.height()), border_{W_, H_} {}

  // Shared progress of all builders of one build; only the reporting builder calls back.
  struct Progress {
    std::atomic<std::size_t> done{0};
    std::atomic<bool> cancelled{false};
    std::size_t total = 1;
  };

  // Full-resolution mesh of the cells whose column lies in [x0, x1). Vertices on a cut column
  // (x0 > 0 or x1 < W-1) are locked: the strip beside it shares them.
  void init_grid(int x0, int x1, std::vector<std::uint32_t>& dropped) {
    number_vertices(x0, x1);
    reserve_mesh(3 * std::size_t(x1 - x0 + 1) * H_, 2 * std::size_t(x1 - x0) * H_);
    std::vector<Mesh::VertexHandle> tri(3);
    auto add_cell = [&](int i, int j) {
      const std::uint32_t s00 = std::uint32_t(j) * W_ + i, s10 = s00 + 1, s01 = s00 + W_, s11 = s01 + 1;
      const std::uint32_t faces[2][3] = {{s00, s10, s11}, {s00, s11, s01}};
      const std::size_t l00 = id_index(i, j), l10 = l00 + 1, l01 = l00 + id_cols_, l11 = l01 + 1;
      const std::size_t ids[2][3] = {{l00, l10, l11}, {l00, l11, l01}};
      for (int k = 0; k < 2; ++k) {
        if (hf_.has_holes() && !(hf_.valid(faces[k][0]) && hf_.valid(faces[k][1]) && hf_.valid(faces[k][2])))
          continue;
        for (int c = 0; c < 3; ++c) tri[c] = Mesh::VertexHandle(int(id_of_[ids[k][c]]));
        if (!add_face(tri).is_valid()) {
          // Cells in tile order always extend the connected fans of their corners (see
          // number_vertices), so only a grid with holes can drop a face.
          if (!hf_.has_holes())
            throw std::logic_error("progressive mesh: the full-resolution grid is not manifold");
          dropped.push_back(std::uint32_t(2 * (j * (W_ - 1) + i) + k));
        }
      }
    };
    if (hf_.has_holes()) {
      // Around holes the faces OpenMesh accepts depend on the order they come in: row by row,
      // as the PM's full-resolution face numbering (dropped faces) expects.
      for (int j = 0; j + 1 < H_; ++j)
        for (int i = x0; i < x1; ++i) add_cell(i, j);
    } else {
      for (std::uint32_t v = 0; v < n_ids_; ++v)  // cell (i,j) has its corner (i,j) first
        if (point(v).x < x1 && point(v).y + 1 < H_) add_cell(point(v).x, point(v).y);
    }
    if (!hf_.has_holes()) grid_x0_ = x0, grid_x1_ = x1;
    for (int j = 0; j < H_; ++j) {
      if (x0 > 0) vs_[id_of_[id_index(x0, j)]].locked = 1;
      if (x1 < W_ - 1) vs_[id_of_[id_index(x1, j)]].locked = 1;
    }
    HugeVector<std::uint32_t>().swap(id_of_);  // needed no more
    edge_err_.assign(mesh_.n_edges(), 0.0);    // edges of the full-resolution grid lie on it
    init_rings();
  }

  // A mesh given by its faces (CCW in (col,row)), e.g. the join of the strips.
  void init_faces(const std::vector<std::array<std::uint32_t, 3>>& faces) {
    std::vector<std::uint8_t> used(hf_.size(), 0);
    for (const auto& f : faces) used[f[0]] = used[f[1]] = used[f[2]] = 1;
    number_vertices(0, W_ - 1, &used);
    reserve_mesh(3 * faces.size() / 2 + 16, faces.size());
    std::vector<Mesh::VertexHandle> tri(3);
    for (const auto& f : faces) {
      for (int c = 0; c < 3; ++c) tri[c] = Mesh::VertexHandle(int(id_of_[f[c]]));  // all columns: the sample
      if (!add_face(tri).is_valid())
        throw std::logic_error("progressive mesh: joined strips are not manifold");
    }
    HugeVector<std::uint32_t>().swap(id_of_);
    edge_err_.assign(mesh_.n_edges(), 0.0);
    init_rings();
    if (err_.metric() == ErrorMetric::Continuous)
      for (auto e : mesh_.edges()) {
        const auto h = mesh_.halfedge_handle(e, 0);
        edge_err_[e.idx()] = err_.segment(point(std::uint32_t(mesh_.from_vertex_handle(h).idx())),
                                          point(std::uint32_t(mesh_.to_vertex_handle(h).idx())));
      }
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
      if (rings_[v].n > 0 && !grid_bound(v)) evaluate(v, /*exact=*/false);
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
      for_each_ring(u, [&](Mesh::HalfedgeHandle g) {
        const std::uint32_t x = std::uint32_t(mesh_.to_vertex_handle(g).idx());
        if (x == w) h = g;
        neighbours_.push_back(x);
        moved_.push_back(g);
      });
      assert(h.is_valid() && geometry_ok(vu, w));
      if (!link_ok(h, neighbours_)) {
        evaluate(u, /*exact=*/true);  // a change around w made the candidate illegal
        continue;
      }
      collapse(h, moved_);
      heap_.remove(u);
      --live;
      ++collapsed_;
      if (err_.metric() == ErrorMetric::Continuous) update_edge_errors(w);
      collapses.push_back(
          Collapse{sample_at(point(u)), sample_at(point(w)), std::ceil(e / quantum) * quantum});
      // The neighbours are measured now, while their rings are in cache, and as far as the
      // keys at the top of the heap (like a popped vertex, see above): most are found to lie
      // above them, and wait with that tighter lower bound instead of being measured again,
      // from cold memory, when a looser bound (ring edges and the error at u only) reaches
      // the top. Instructions on the 241 x 241 crop: 3.82 G -> 3.52 G (cutoff 0: 3.88 G,
      // twice the largest child key: 4.37 G).
      for (std::uint32_t n : neighbours_) prefetch_vertex(n);
      for (std::uint32_t n : neighbours_) prefetch_ring(n);
      for (std::uint32_t n : neighbours_) prefetch_ring_data(n);
      for (std::uint32_t n : neighbours_) evaluate(n, /*exact=*/true, heap_.children_max_error());
      if (collapsed_ * kCompactAt >= n_ids_) compact();
      if (++since_report == 4096) {
        const std::size_t done = progress.done.fetch_add(since_report) + since_report;
        since_report = 0;
        if (progress.cancelled) throw std::runtime_error("progressive mesh build cancelled");
        if (report && opt_.progress && !opt_.progress(std::min(1.0, double(done) / double(progress.total)))) {
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

  // Vertex numbering for locality. The collapse order is global by error, so every collapse
  // works at a random place of the mesh; what it touches there (the rings of u and its
  // neighbours: halfedges, edge errors, positions, heights, heap positions) should lie in a few
  // cache lines and one page. Vertex ids therefore follow tiles of kTile x kTile samples, the
  // tiles row by row and Z-order (Morton) inside a tile, over the columns [x0, x1]; samples
  // outside them, or not in `used` when given, get no id, so that every per-vertex array
  // (OpenMesh's included) holds only the vertices this builder works on. Cells are created in
  // the same order, so a ring's halfedges are close too. In this order a cell's left, upper and
  // upper-left neighbours always come before it, so each new face extends connected fans at
  // its corners and OpenMesh accepts every face of a hole-free grid. The numbering depends on
  // the grid (and `used`) only, so the PM stays a function of the heightfield; leaving samples
  // out keeps the order of the others, and with it every tie-break by vertex id.
  static constexpr int kTile = 64;
  void number_vertices(int x0, int x1, const std::vector<std::uint8_t>* used = nullptr) {
    std::vector<std::uint32_t> sample_of;  // vertex id -> sample index
    sample_of.reserve(used ? std::size_t(std::count(used->begin(), used->end(), 1))
                           : std::size_t(x1 + 1 - x0) * std::size_t(H_));
    std::vector<std::uint32_t> z_order(std::size_t(kTile) * kTile);  // Morton code -> dx + kTile * dy
    for (std::uint32_t m = 0; m < z_order.size(); ++m) {
      std::uint32_t dx = 0, dy = 0;
      for (int b = 0; 2 * b < 32 && (m >> (2 * b)) != 0; ++b)
        dx |= ((m >> (2 * b)) & 1u) << b, dy |= ((m >> (2 * b + 1)) & 1u) << b;
      z_order[m] = dx + kTile * dy;
    }
    for (int ty = 0; ty < H_; ty += kTile)
      for (int tx = x0; tx <= x1; tx += kTile) {
        const int tw = std::min(kTile, x1 + 1 - tx), th = std::min(kTile, H_ - ty);
        for (std::uint32_t c : z_order) {  // a partial tile skips the codes outside it
          const int dx = int(c % kTile), dy = int(c / kTile);
          if (dx >= tw || dy >= th) continue;
          const std::uint32_t s = std::uint32_t(std::size_t(ty + dy) * W_ + tx + dx);
          if (!used || (*used)[s]) sample_of.push_back(s);
        }
      }
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

  // Reserves the mesh and adds all vertices. OpenMesh's element and property arrays are the
  // largest, most randomly accessed memory of the build (the halfedges alone ~100 bytes per
  // vertex): they are advised to use transparent huge pages before their pages are touched
  // (reserve() only allocates), so that ring walks at random places do not also miss the TLB.
  void reserve_mesh(std::size_t n_edges, std::size_t n_faces) {
    const std::size_t nv = n_ids_;
    mesh_.reserve(nv, n_edges, n_faces);
    const auto v0 = mesh_.add_vertex(Mesh::Point(0, 0, 0));
    advise_huge(&mesh_.vertex(v0), nv * sizeof(Mesh::Vertex));
    advise_huge(&mesh_.point(v0), nv * sizeof(Mesh::Point));
    advise_huge(&mesh_.status(v0), nv * sizeof(OpenMesh::Attributes::StatusInfo));
    for (std::size_t i = 1; i < nv; ++i) mesh_.add_vertex(Mesh::Point(0, 0, 0));
    reserved_edges_ = n_edges, reserved_faces_ = n_faces;
    // Only triangles of 256 cells and more pass through the cache, and they are few: 66k
    // lookups (22k hits) in a whole N44W072 build, against 15 M measurements of smaller
    // ones. 2^16 slots (1.5 MiB, cache-resident) hold them, on any grid; the 2^22 slots
    // used before cost 96 MiB of page faults per builder for nothing.
    cache_.reset(16);
  }

  // mesh_.add_face of a triangle; the edge and face arrays are advised once the first face
  // made them reachable (the pages of their first 2 MiB are not advised, the rest is still
  // untouched).
  Mesh::FaceHandle add_face(const std::vector<Mesh::VertexHandle>& tri) {
    const auto f = add_triangle(tri.data());
    if (f.is_valid() && mesh_.n_faces() == 1) {
      const auto e0 = Mesh::EdgeHandle(0);
      advise_huge(&mesh_.edge(e0), reserved_edges_ * sizeof(Mesh::Edge));
      advise_huge(&mesh_.status(e0), reserved_edges_ * sizeof(OpenMesh::Attributes::StatusInfo));
      advise_huge(&mesh_.face(f), reserved_faces_ * sizeof(Mesh::Face));
      advise_huge(&mesh_.status(f), reserved_faces_ * sizeof(OpenMesh::Attributes::StatusInfo));
    }
    return f;
  }

  // PolyConnectivity::add_face for a triangle, step for step the same algorithm (so the same
  // edges, in the same order, the same links and outgoing halfedges: the PM does not change),
  // written against the kernel's inline accessors. OpenMesh's goes through library calls that
  // check every handle, and creating the grid's 1.4 M faces per strip through it took a tenth
  // of the strip's build. The cases that change nothing here and go to OpenMesh instead: a
  // face that would make a vertex or an edge non-manifold (OpenMesh reports it and refuses),
  // and one whose existing edges first need a patch of faces re-linked around a vertex.
  Mesh::FaceHandle add_triangle(const Mesh::VertexHandle* v) {
    Mesh::HalfedgeHandle he[3];
    bool is_new[3], adjust[3] = {false, false, false};
    for (int i = 0; i < 3; ++i) {
      const Mesh::VertexHandle from = v[i], to = v[(i + 1) % 3];
      const auto out = mesh_.halfedge_handle(from);
      if (out.is_valid() && !mesh_.is_boundary(out)) return mesh_.add_face(v, 3);  // not a boundary vertex
      he[i] = find_halfedge(from, to);
      is_new[i] = !he[i].is_valid();
      if (!is_new[i] && !mesh_.is_boundary(he[i])) return mesh_.add_face(v, 3);  // the edge has two faces
    }
    for (int i = 0; i < 3; ++i) {
      const int ii = (i + 1) % 3;
      if (!is_new[i] && !is_new[ii] && mesh_.next_halfedge_handle(he[i]) != he[ii])
        return mesh_.add_face(v, 3);
    }
    for (int i = 0; i < 3; ++i)
      if (is_new[i]) he[i] = mesh_.new_edge(v[i], v[(i + 1) % 3]);
    const auto fh = mesh_.new_face();
    mesh_.set_halfedge_handle(fh, he[2]);
    std::pair<Mesh::HalfedgeHandle, Mesh::HalfedgeHandle> links[9];
    int n_links = 0;
    for (int i = 0; i < 3; ++i) {
      const int ii = (i + 1) % 3;
      const Mesh::VertexHandle vh = v[ii];
      const auto inner_prev = he[i], inner_next = he[ii];
      if (is_new[i] || is_new[ii]) {
        const auto outer_prev = mesh_.opposite_halfedge_handle(inner_next);
        const auto outer_next = mesh_.opposite_halfedge_handle(inner_prev);
        if (is_new[i] && !is_new[ii]) {
          links[n_links++] = {mesh_.prev_halfedge_handle(inner_next), outer_next};
          mesh_.set_halfedge_handle(vh, outer_next);
        } else if (!is_new[i]) {
          const auto boundary_next = mesh_.next_halfedge_handle(inner_prev);
          links[n_links++] = {outer_prev, boundary_next};
          mesh_.set_halfedge_handle(vh, boundary_next);
        } else if (!mesh_.halfedge_handle(vh).is_valid()) {
          mesh_.set_halfedge_handle(vh, outer_next);
          links[n_links++] = {outer_prev, outer_next};
        } else {
          const auto boundary_next = mesh_.halfedge_handle(vh);
          links[n_links++] = {mesh_.prev_halfedge_handle(boundary_next), outer_next};
          links[n_links++] = {outer_prev, boundary_next};
        }
        links[n_links++] = {inner_prev, inner_next};
      } else {
        adjust[ii] = mesh_.halfedge_handle(vh) == inner_next;
      }
      mesh_.set_face_handle(he[i], fh);
    }
    for (int i = 0; i < n_links; ++i) mesh_.set_next_halfedge_handle(links[i].first, links[i].second);
    for (int i = 0; i < 3; ++i)
      if (adjust[i]) adjust_outgoing(v[i]);
    return fh;
  }

  static void advise_huge([[maybe_unused]] const void* p, [[maybe_unused]] std::size_t bytes) {
#ifdef MADV_HUGEPAGE
    constexpr std::uintptr_t kHuge = std::uintptr_t(2) << 20;
    const std::uintptr_t begin = (std::uintptr_t(p) + kHuge - 1) & ~(kHuge - 1);
    const std::uintptr_t end = (std::uintptr_t(p) + bytes) & ~(kHuge - 1);
    if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);  // advice only
#endif
  }

  // After a collapse, the neighbours' rings are read one after the other by evaluate(); these
  // two start the loads of all of them at once: the halfedges of the rings, then what
  // evaluate() reads through them (ring vertices' records, the crossing errors of ring edges).
  void prefetch_ring(std::uint32_t v) const {
    const Ring& r = rings_[v];
    const std::uint32_t n = std::min(r.n, kRingCap);
    for (std::uint32_t i = 0; i < n; ++i)
      __builtin_prefetch(&mesh_.halfedge(Mesh::HalfedgeHandle(int(r.h[i]))));
  }
  void prefetch_ring_data(std::uint32_t v) const {
    const Ring& r = rings_[v];
    const std::uint32_t n = std::min(r.n, kRingCap);
    for (std::uint32_t i = 0; i < n; ++i) {
      const auto h = Mesh::HalfedgeHandle(int(r.h[i]));
      __builtin_prefetch(&sites_[std::uint32_t(mesh_.to_vertex_handle(h).idx())]);
      __builtin_prefetch(&edge_err_[std::uint32_t(mesh_.next_halfedge_handle(h).idx()) >> 1]);
    }
  }

  // Collapses leave their deleted vertices, edges and faces in every array, so the live data
  // of a region thins out: a ring spreads over more cache lines, and the memory the loop reads
  // at random stays as large as at the start while the mesh shrinks. Once 1/kCompactAt of the
  // vertices are deleted, compact() moves the live elements down in place, keeping their
  // order: every tie-break by vertex id, every ring's order and the heap's order stay, so the
  // PM is the same as without it (the caches are keyed by sample, not by id). Each pass costs
  // a sequential sweep of the arrays; every quarter of the vertices (rather than every half)
  // measured 0.96x the build time (full tile, 14 alternating pairs).
  static constexpr std::size_t kCompactAt = 4;
  void compact() {
    const std::uint32_t nv = std::uint32_t(mesh_.n_vertices()), ne = std::uint32_t(mesh_.n_edges()),
                        nf = std::uint32_t(mesh_.n_faces());
    // Old -> new ids, UINT32_MAX: deleted. Kept between calls: fresh pages cost page faults.
    auto &vmap = vmap_, &emap = emap_, &fmap = fmap_;
    vmap.resize(nv), emap.resize(ne), fmap.resize(nf);
    std::uint32_t lv = 0, le = 0, lf = 0;
    for (std::uint32_t v = 0; v < nv; ++v)
      vmap[v] = mesh_.status(Mesh::VertexHandle(int(v))).deleted() ? UINT32_MAX : lv++;
    for (std::uint32_t e = 0; e < ne; ++e)
      emap[e] = mesh_.status(Mesh::EdgeHandle(int(e))).deleted() ? UINT32_MAX : le++;
    for (std::uint32_t f = 0; f < nf; ++f)
      fmap[f] = mesh_.status(Mesh::FaceHandle(int(f))).deleted() ? UINT32_MAX : lf++;
    const auto mh = [&](Mesh::HalfedgeHandle h) {  // a live halfedge's new id
      if (!h.is_valid()) return h;
      const std::uint32_t i = std::uint32_t(h.idx());
      return Mesh::HalfedgeHandle(int(2 * emap[i >> 1] + (i & 1)));
    };
    // Element k moves to map[k] <= k, in increasing k, so nothing is overwritten before it is read.
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (vmap[v] == UINT32_MAX) continue;
      const auto vh = Mesh::VertexHandle(int(v)), vj = Mesh::VertexHandle(int(vmap[v]));
      mesh_.set_halfedge_handle(vj, mh(mesh_.halfedge_handle(vh)));
      mesh_.status(vj) = mesh_.status(vh);
      VertexState& sv = vs_[vmap[v]];
      sv = vs_[v];
      sites_[vmap[v]] = sites_[v];
      if (sv.target != UINT32_MAX) sv.target = vmap[sv.target];  // a deleted target is never used again
      Ring& r = rings_[vmap[v]];
      r = rings_[v];
      for (std::uint32_t i = 0; i < std::min(r.n, kRingCap); ++i)
        r.h[i] = std::uint32_t(mh(Mesh::HalfedgeHandle(int(r.h[i]))).idx());
    }
    // A halfedge's prev is set by set_next_halfedge_handle of its predecessor, and never read
    // from a moved record (it may not have been written yet).
    for (std::uint32_t e = 0; e < ne; ++e) {
      if (emap[e] == UINT32_MAX) continue;
      for (std::uint32_t k = 0; k < 2; ++k) {
        const auto h = Mesh::HalfedgeHandle(int(2 * e + k)), hj = Mesh::HalfedgeHandle(int(2 * emap[e] + k));
        const auto to = mesh_.to_vertex_handle(h);
        const auto next = mesh_.next_halfedge_handle(h);
        const auto f = mesh_.face_handle(h);
        mesh_.set_vertex_handle(hj, Mesh::VertexHandle(int(vmap[std::uint32_t(to.idx())])));
        mesh_.set_face_handle(hj, f.is_valid() ? Mesh::FaceHandle(int(fmap[std::uint32_t(f.idx())])) : f);
        mesh_.set_next_halfedge_handle(hj, mh(next));
      }
      mesh_.status(Mesh::EdgeHandle(int(emap[e]))) = mesh_.status(Mesh::EdgeHandle(int(e)));
      edge_err_[emap[e]] = edge_err_[e];
    }
    for (std::uint32_t f = 0; f < nf; ++f) {
      if (fmap[f] == UINT32_MAX) continue;
      const auto fh = Mesh::FaceHandle(int(f)), fj = Mesh::FaceHandle(int(fmap[f]));
      mesh_.set_halfedge_handle(fj, mh(mesh_.halfedge_handle(fh)));
      mesh_.status(fj) = mesh_.status(fh);
    }
    mesh_.resize(lv, le, lf);
    vs_.resize(lv);
    sites_.resize(lv);
    rings_.resize(lv);
    edge_err_.resize(le);
    heap_.renumber(vmap);
    n_ids_ = lv;
    collapsed_ = 0;
  }

  // Starts loading the per-vertex data that evaluate(v) and the heap read first.
  void prefetch_vertex(std::uint32_t v) const {
    if (v == UINT32_MAX) return;
    __builtin_prefetch(&rings_[v]);
    __builtin_prefetch(&vs_[v]);
    __builtin_prefetch(&sites_[v]);
  }

  // Every vertex's outgoing halfedges, in the order for_each_outgoing visits them, in one
  // cache line. Walking a ring through OpenMesh is a chain of dependent loads (each halfedge
  // names the next), one cache miss after another at a random place of the mesh: from the
  // record, the CPU issues all of the ring's loads at once. Only a collapse changes rings,
  // and only those of w and of the two wing vertices (see collapse): the other neighbours of
  // u keep their halfedges, now pointing at w, in the same order. Degrees above kRingCap
  // (1 in 2000 evaluations on N44W072) are walked through OpenMesh.
  static constexpr std::uint32_t kRingCap = 15;
  struct alignas(64) Ring {
    std::uint32_t h[kRingCap];
    std::uint32_t n;  // the degree; the halfedges are stored when n <= kRingCap
  };
  static_assert(sizeof(Ring) == 64);
  void refresh_ring(std::uint32_t v) {
    Ring& r = rings_[v];
    std::uint32_t n = 0;
    for_each_outgoing(Mesh::VertexHandle(int(v)), [&](Mesh::HalfedgeHandle h) {
      if (n < kRingCap) r.h[n] = std::uint32_t(h.idx());
      ++n;
    });
    r.n = n;
  }
  void init_rings() {
    rings_.resize(n_ids_);
    for (std::uint32_t v = 0; v < n_ids_; ++v) refresh_ring(v);
  }
  // for_each_outgoing(v, f) from v's record.
  template <class F>
  void for_each_ring(std::uint32_t v, F&& f) const {
    const Ring& r = rings_[v];
    if (r.n > kRingCap) return for_each_outgoing(Mesh::VertexHandle(int(v)), f);
    assert(ring_matches(v));
    for (std::uint32_t i = 0; i < r.n; ++i) f(Mesh::HalfedgeHandle(int(r.h[i])));
  }
  bool ring_matches(std::uint32_t v) const {
    const Ring& r = rings_[v];
    std::uint32_t n = 0;
    bool same = true;
    for_each_outgoing(Mesh::VertexHandle(int(v)), [&](Mesh::HalfedgeHandle h) {
      if (n < kRingCap && r.h[n] != std::uint32_t(h.idx())) same = false;
      ++n;
    });
    return same && n == r.n;
  }

  // Outgoing halfedges of v, calling f(h) for each. Hand-written with the kernel's inline
  // accessors: OpenMesh's circulators validate every handle through a library call.
  template <class F>
  void for_each_outgoing(Mesh::VertexHandle v, F&& f) const {
    const auto start = mesh_.halfedge_handle(v);
    if (!start.is_valid()) return;
    auto h = start;
    do {
      f(h);
      h = mesh_.next_halfedge_handle(mesh_.opposite_halfedge_handle(h));
    } while (h != start);
  }

  // The collapse of halfedge h (u -> w), written against OpenMesh's kernel so that it runs
  // without the library's calls and handle checks (a tenth of the build went there). It leaves
  // exactly the connectivity PolyConnectivity::collapse leaves: the same elements deleted, the
  // same outgoing halfedge at every vertex (a vertex keeps a boundary one when it has one), so
  // ring walks, and with them every tie-break, see the mesh they saw before. Two faces beside
  // the edge fold into loops of two halfedges; each loop keeps the edge (w, wing) and deletes
  // the edge (u, wing), so the stored crossing error of every edge that survives still
  // describes its segment, except for u's other edges, which now start at w.
  // outgoing_u: u's outgoing halfedges (the caller has just walked u's ring).
  void collapse(Mesh::HalfedgeHandle h, const std::vector<Mesh::HalfedgeHandle>& outgoing_u) {
    const auto hn = mesh_.next_halfedge_handle(h), hp = mesh_.prev_halfedge_handle(h);
    const auto o = mesh_.opposite_halfedge_handle(h);
    const auto on = mesh_.next_halfedge_handle(o), op = mesh_.prev_halfedge_handle(o);
    const auto fh = mesh_.face_handle(h), fo = mesh_.face_handle(o);
    const auto vw = mesh_.to_vertex_handle(h), vu = mesh_.to_vertex_handle(o);
    const auto wing_h = fh.is_valid() ? mesh_.to_vertex_handle(hn) : Mesh::VertexHandle();
    const auto wing_o = fo.is_valid() ? mesh_.to_vertex_handle(on) : Mesh::VertexHandle();
    // adjust_outgoing() looks for a boundary halfedge and finds none around an interior
    // vertex; the collapse of an interior edge makes no vertex a boundary one, so the walks
    // are skipped for the vertices that are interior now (a boundary vertex's outgoing
    // halfedge is a boundary one).
    const auto if_interior = [&](Mesh::VertexHandle v) {
      return v.is_valid() && !mesh_.is_boundary(mesh_.halfedge_handle(v)) ? v : Mesh::VertexHandle();
    };
    const Interior interior = {if_interior(vw), if_interior(wing_h), if_interior(wing_o)};
    for (const auto g : outgoing_u) mesh_.set_vertex_handle(mesh_.opposite_halfedge_handle(g), vw);
    mesh_.set_next_halfedge_handle(hp, hn);
    mesh_.set_next_halfedge_handle(op, on);
    if (fh.is_valid()) mesh_.set_halfedge_handle(fh, hn);
    if (fo.is_valid()) mesh_.set_halfedge_handle(fo, on);
    if (mesh_.halfedge_handle(vw) == o) mesh_.set_halfedge_handle(vw, hn);
    if (!is_interior(vw, interior)) adjust_outgoing(vw);
    mesh_.set_isolated(vu);
    mesh_.status(mesh_.edge_handle(h)).set_deleted(true);
    mesh_.status(vu).set_deleted(true);
    if (mesh_.next_halfedge_handle(mesh_.next_halfedge_handle(hn)) == hn)
      collapse_loop(mesh_.next_halfedge_handle(hn), interior);
    if (mesh_.next_halfedge_handle(mesh_.next_halfedge_handle(on)) == on) collapse_loop(on, interior);
    // The rings that changed (see Ring).
    rings_[std::uint32_t(vu.idx())].n = 0;
    refresh_ring(std::uint32_t(vw.idx()));
    if (wing_h.is_valid()) refresh_ring(std::uint32_t(wing_h.idx()));
    if (wing_o.is_valid()) refresh_ring(std::uint32_t(wing_o.idx()));
  }

  // collapse(): w and the wings, each where it is an interior vertex, else invalid.
  using Interior = std::array<Mesh::VertexHandle, 3>;
  static bool is_interior(Mesh::VertexHandle v, const Interior& interior) {
    return v.is_valid() && (v == interior[0] || v == interior[1] || v == interior[2]);
  }

  // Removes the loop of two halfedges h0, next(h0) that a collapse left: h0's edge goes, and
  // next(h0) takes the place of h0's opposite in the face on the other side.
  void collapse_loop(Mesh::HalfedgeHandle h0, const Interior& interior) {
    const auto h1 = mesh_.next_halfedge_handle(h0);
    const auto o0 = mesh_.opposite_halfedge_handle(h0), o1 = mesh_.opposite_halfedge_handle(h1);
    const auto v0 = mesh_.to_vertex_handle(h0), v1 = mesh_.to_vertex_handle(h1);
    const auto fh = mesh_.face_handle(h0), fo = mesh_.face_handle(o0);
    assert(mesh_.next_halfedge_handle(h1) == h0 && h1 != o0);
    mesh_.set_next_halfedge_handle(h1, mesh_.next_halfedge_handle(o0));
    mesh_.set_next_halfedge_handle(mesh_.prev_halfedge_handle(o0), h1);
    mesh_.set_face_handle(h1, fo);
    mesh_.set_halfedge_handle(v0, h1);
    if (!is_interior(v0, interior)) adjust_outgoing(v0);
    mesh_.set_halfedge_handle(v1, o1);
    if (!is_interior(v1, interior)) adjust_outgoing(v1);
    if (fo.is_valid() && mesh_.halfedge_handle(fo) == o0) mesh_.set_halfedge_handle(fo, h1);
    if (fh.is_valid()) {
      mesh_.set_halfedge_handle(fh, Mesh::HalfedgeHandle());
      mesh_.status(fh).set_deleted(true);
    }
    mesh_.status(mesh_.edge_handle(h0)).set_deleted(true);
  }

  // Makes v's outgoing halfedge its first boundary one in clockwise order from the current
  // one, if it has any (OpenMesh's convention, which boundary tests rely on).
  void adjust_outgoing(Mesh::VertexHandle v) {
    const auto start = mesh_.halfedge_handle(v);
    if (!start.is_valid()) return;
    auto h = start;
    do {
      if (mesh_.is_boundary(h)) {
        mesh_.set_halfedge_handle(v, h);
        return;
      }
      h = mesh_.next_halfedge_handle(mesh_.opposite_halfedge_handle(h));
    } while (h != start);
  }

  // Crossing errors of the edges u's collapse into w moved to w (moved_: u's outgoing
  // halfedges before the collapse); the others around w kept their segments (see collapse).
  void update_edge_errors(std::uint32_t w) {
    for (const auto g : moved_) {
      const auto e = mesh_.edge_handle(g);
      if (mesh_.status(e).deleted()) continue;
      edge_err_[e.idx()] = spoke_error(w, std::uint32_t(mesh_.to_vertex_handle(g).idx()), 1e300);
    }
  }

  // Crossing error of the segment (w, x), through a small direct-mapped cache: the same spokes
  // are measured again whenever a vertex is re-evaluated. The table (512 KiB) stays in cache.
  // Keyed by sample index, which compact() does not change; measured from the endpoint with
  // the smaller vertex id, an order compact() keeps.
  double spoke_error(std::uint32_t w, std::uint32_t x, double cutoff) {
    const GridPoint pa = point(std::min(w, x)), pb = point(std::max(w, x));
    // A short segment crosses few grid lines: measuring it costs less than a cache miss.
    if (std::abs(pa.x - pb.x) + std::abs(pa.y - pb.y) <= kShortSpoke) return err_.segment(pa, pb, cutoff);
    const std::uint32_t a = sample_at(pa), b = sample_at(pb);
    SpokeSlot& s =
        spokes_[(std::uint64_t(a) * 0x9E3779B97F4A7C15ull ^ std::uint64_t(b) * 0xC2B2AE3D27D4EB4Full) >> 49];
    if (s.a == a && s.b == b) {
      if (s.value >= 0) return s.value;        // exact
      if (-s.value > cutoff) return -s.value;  // a lower bound above the cutoff
    }
    const double e = err_.segment(pa, pb, cutoff);
    s = SpokeSlot{a, b, e <= cutoff ? e : -e};  // lower bounds (> cutoff >= 0) stored negated
    return e;
  }

  Mesh::HalfedgeHandle find_halfedge(Mesh::VertexHandle from, Mesh::VertexHandle to) const {
    Mesh::HalfedgeHandle found;
    for_each_outgoing(from, [&](Mesh::HalfedgeHandle h) {
      if (mesh_.to_vertex_handle(h) == to) found = h;
    });
    return found;
  }

  // Topological legality of collapsing halfedge h (u -> w), the link condition of Dey et al.
  // as OpenMesh's is_collapse_ok checks it, without its per-call allocations: the common
  // neighbours of u and w are exactly the opposite vertices of the faces beside the edge, and
  // an interior edge may not join two boundary vertices.
  // ring_u: the heads of u's outgoing halfedges.
  bool link_ok(Mesh::HalfedgeHandle h, const std::vector<std::uint32_t>& ring_u) const {
    const auto vu = mesh_.from_vertex_handle(h), vw = mesh_.to_vertex_handle(h);
    const auto o = mesh_.opposite_halfedge_handle(h);
    const bool edge_boundary = mesh_.is_boundary(h) || mesh_.is_boundary(o);
    if (!edge_boundary && mesh_.is_boundary(vu) && mesh_.is_boundary(vw)) return false;
    std::uint32_t wings[2] = {UINT32_MAX, UINT32_MAX};
    if (!mesh_.is_boundary(h))
      wings[0] = std::uint32_t(mesh_.to_vertex_handle(mesh_.next_halfedge_handle(h)).idx());
    if (!mesh_.is_boundary(o))
      wings[1] = std::uint32_t(mesh_.to_vertex_handle(mesh_.next_halfedge_handle(o)).idx());
    if (wings[0] == wings[1]) return false;
    // Common neighbours by comparing the two (short) rings: no per-vertex marks to miss in cache.
    int common = 0;
    bool ok = true;
    for_each_ring(std::uint32_t(vw.idx()), [&](Mesh::HalfedgeHandle g) {
      const std::uint32_t x = std::uint32_t(mesh_.to_vertex_handle(g).idx());
      if (std::find(ring_u.begin(), ring_u.end(), x) == ring_u.end()) return;
      if (x != wings[0] && x != wings[1]) ok = false;
      ++common;
    });
    return ok && common == (wings[0] != UINT32_MAX) + (wings[1] != UINT32_MAX);
  }

  // Plan-view legality of u -> w: every face around u that does not contain w stays CCW.
  bool geometry_ok(Mesh::VertexHandle vu, std::uint32_t w) const {
    const GridPoint pw = point(w);
    bool ok = true;
    for_each_outgoing(vu, [&](Mesh::HalfedgeHandle h) {
      if (mesh_.is_boundary(h)) return;
      const auto hn = mesh_.next_halfedge_handle(h);
      const std::uint32_t a = std::uint32_t(mesh_.to_vertex_handle(h).idx());
      const std::uint32_t b = std::uint32_t(mesh_.to_vertex_handle(hn).idx());
      if (a != w && b != w && orient2d(pw, point(a), point(b)) <= 0) ok = false;
    });
    return ok;
  }

  double cached_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, double cutoff) {
    const GridPoint pa = point(a), pb = point(b), pc = point(c);
    const std::int64_t area2 = orient2d(pa, pb, pc);
    if (area2 < 512) return err_.samples_in_triangle(pa, pb, pc, cutoff);
    std::uint32_t s[3] = {sample_at(pa), sample_at(pb), sample_at(pc)};  // see spoke_error
    std::sort(s, s + 3);
    double value;
    bool exact;
    if (cache_.find(s[0], s[1], s[2], value, exact) && (exact || value > cutoff)) return value;
    value = err_.samples_in_triangle(pa, pb, pc, cutoff);
    cache_.store(s[0], s[1], s[2], value, value <= cutoff);
    return value;
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
    if (border_.corner(pu) || su.locked || rings_[u].n == 0) {
      heap_.remove(u);
      return;
    }
    // One walk around u: its ring vertices in order (ringv_[k] = head of the k-th outgoing
    // halfedge), their positions relative to u and heights, and the faces (u, ringv_[k],
    // ringv_[k-1]) that exist, with the crossing error of their edge opposite u.
    const bool continuous = err_.metric() == ErrorMetric::Continuous;
    ringv_.clear();
    ringh_.clear();
    ring_.clear();
    rloc_.clear();
    bool boundary = false;
    {
      std::uint32_t k = 0;
      for_each_ring(u, [&](Mesh::HalfedgeHandle h) {
        const std::uint32_t a = std::uint32_t(mesh_.to_vertex_handle(h).idx());
        ringv_.push_back(a);
        ringh_.push_back(h);
        const GridPoint pa = point(a);
        rloc_.push_back(Local{std::int64_t(pa.x) - pu.x, std::int64_t(pa.y) - pu.y, sites_[a].z});
        if (mesh_.is_boundary(h)) {
          boundary = true;
        } else {
          // The face's third corner is the previous ring vertex (filled in below, so that
          // the head of next(h) need not be loaded); its edge error is at next(h)'s edge.
          RingFace f{};
          f.a = a, f.ka = k;
          f.edge_error = continuous ? edge_err_[mesh_.edge_handle(mesh_.next_halfedge_handle(h)).idx()] : 0.0;
          ring_.push_back(f);
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
    if (boundary) {
      // Only along its own grid border line, and only when both boundary neighbours are on it
      // (otherwise u is on the boundary of a hole, which must keep its shape; grid_border.hpp).
      // The vertex's outgoing halfedge is its boundary one: ringv_[0] is the next boundary
      // vertex and ringv_[n-1] the previous one.
      const BorderLine line = border_.line(pu);
      const std::uint32_t next = ringv_[0], prev = ringv_[n - 1];
      if (line != BorderLine::None && border_.on(line, point(next)) && border_.on(line, point(prev))) {
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
    for (Candidate& c : cand_) {
      const Local& lw = rl[c.k];
      // With positions relative to u: orient(w, a, b) = cross(a, b) + X(a) - X(b), where
      // X(x) = cross(w, x); orient(w, a, u) = X(a) and orient(b, w, u) = -X(b). u lies in
      // the first new triangle (w, a, b) whose wedge at w contains the direction w -> u:
      // orient(w, a, u) >= 0 and orient(w, u, b) >= 0.
      double lb = ring_edges;
      bool flat = false;
      for (std::size_t j = 0; j < nf; ++j) {
        const RingFace& f = fs[j];
        if (f.ka == c.k || f.kb == c.k) continue;
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
      c.lower = lb;
      c.tie = tie_of(pu, point(c.w));
      cand_[kept++] = c;
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
      if (continuous)  // the new spokes (w, x) to ring vertices x not already joined to w
        for (std::uint32_t k = 0; k < n; ++k) {
          // (w, x) is an edge of u's ring when x is w's ring neighbour across an existing face.
          const std::uint32_t kn = c.k + 1 == n ? 0 : c.k + 1, kp = c.k == 0 ? n - 1 : c.k - 1;
          if (k == c.k || (k == kn && face_at_[kn]) || (k == kp && face_at_[c.k])) continue;
          e = std::max(e, spoke_error(c.w, ringv_[k], limit));
          if (e > limit) break;
        }
      if (e <= limit)
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
      if (!link_ok(ringh_[c.k], ringv_)) continue;
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
  LInfError err_;
  int W_, H_;
  GridBorder border_;
  Mesh mesh_;
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
  TriangleCache cache_;
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
  HugeVector<Ring> rings_;                   // by vertex id
  // While the mesh is made: vertex id of sample (i, j) at id_of_[id_index(i, j)], over the
  // builder's columns only.
  HugeVector<std::uint32_t> id_of_;
  int id_x0_ = 0;
  std::size_t id_cols_ = 0;
  std::size_t id_index(int i, int j) const { return std::size_t(j) * id_cols_ + std::size_t(i - id_x0_); }
  HugeVector<std::uint32_t> vmap_, emap_, fmap_;  // compact()'s maps
  std::uint32_t n_ids_ = 0;          // vertex ids are 0 .. n_ids_ - 1 (see number_vertices, compact)
  int grid_x0_ = -1, grid_x1_ = -1;  // init_grid's columns when the grid has no holes
  std::size_t collapsed_ = 0;        // collapses since the last compact()

  std::size_t reserved_edges_ = 0, reserved_faces_ = 0;
  struct SpokeSlot {
    std::uint32_t a = UINT32_MAX, b = 0;
    double value = 0;  // exact error when >= 0, else minus a lower bound
  };
  std::vector<SpokeSlot> spokes_ = std::vector<SpokeSlot>(1 << 15);  // 512 KiB: stays in L2
  static constexpr int kShortSpoke = 6;
  std::vector<Candidate> cand_;

  struct RingFace {        // the face (u, a, b) of u's ring
    std::uint32_t a, b;    // vertex ids
    std::uint32_t ka, kb;  // their ring indices: kb = ka - 1 (mod n)
    std::int64_t cross;    // cross(a - u, b - u), twice the face's area
    double edge_error;     // crossing error of the edge (a, b)
  };
  std::vector<RingFace> ring_;
  HugeVector<double> edge_err_;
};

}  // namespace

ProgressiveMesh ProgressiveMesh::build(const Heightfield& hf, const BuildOptions& options) {
  if (hf.width() < 2 || hf.height() < 2)
    throw std::invalid_argument("progressive mesh: grid is " + std::to_string(hf.width()) + " x " +
                                std::to_string(hf.height()) + "; at least 2 x 2 samples are needed");
  if (hf.size() >= (std::size_t(1) << 31))
    throw std::invalid_argument("progressive mesh: grid of " + std::to_string(hf.size()) +
                                " samples is too large for one PM; cut it into blocks");
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i) && !std::isfinite(hf[i]))
      throw std::invalid_argument("progressive mesh: sample " + std::to_string(i) + " of " + hf.source +
                                  " is not finite; fill or mask voids first");
  const double quantum = error_quantum_for(hf);
  std::vector<Collapse> collapses;
  collapses.reserve(hf.size());
  std::vector<std::uint32_t> dropped;
  Builder::Progress progress;
  std::size_t valid = 0;
  for (std::size_t i = 0; i < hf.size(); ++i) valid += hf.valid(i);
  progress.total = valid > 4 ? valid - 4 : 1;

  // The number of strips depends on the grid only, never on the machine, so that the same
  // heightfield always gives the same PM; threads only decide how many strips run at once.
  // Two strips: this machine kind has two cores, and every cut column stays at full
  // resolution below the join error, so more cuts cost triangles at fine levels.
  const int strips =
      (options.parallel_strips && hf.width() - 1 >= 256 && hf.size() >= (1u << 16) && !hf.has_holes()) ? 2
                                                                                                       : 1;
  const int threads = std::max(
      1, std::min(strips, options.threads > 0 ? options.threads
                                              : int(std::max(1u, std::thread::hardware_concurrency()))));
  // With holes the union of two manifold strips can pinch at a cut vertex; those build whole.
  if (strips == 1) {
    Builder b(hf, options);
    b.init_grid(0, hf.width() - 1, dropped);
    b.run(collapses, quantum, 0, progress, /*report=*/true);
  } else {
    // Phase 1: vertical strips sharing their cut columns (locked), decimated in parallel
    // until each keeps 1/kStripKeep of its vertices. The join below runs on one thread, so
    // the strips go far: a smaller join costs only a higher common error, below which the cut
    // column stays at full resolution (about 2 triangles per row, at coarse levels only). Collapses of
    // different strips are independent (their 1-rings never cross a cut column), so any interleaving of the
    // strips' sequences is a valid sequence; they are merged in error order below.
    constexpr std::size_t kStripKeep = 128;
    std::vector<int> cuts(strips + 1);
    for (int t = 0; t <= strips; ++t) cuts[t] = int(std::int64_t(hf.width() - 1) * t / strips);
    std::vector<std::vector<Collapse>> seq(strips);
    std::vector<std::vector<std::uint32_t>> drop(strips);
    std::vector<std::exception_ptr> failure(strips);
    auto strip = [&](int t) {
      try {
        Builder b(hf, options);
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
    // A strip that went further than the others would put its higher-error collapses before
    // the others' lower-error ones: keep every strip's sequence only up to the smallest of
    // their final prefix maxima, and leave the rest to the joined mesh.
    double common = 1e300;
    for (auto& q : seq) {
      double m = 0;
      for (auto& c : q) m = std::max(m, c.error);
      common = std::min(common, m);
    }
    std::vector<std::size_t> keep(strips), at(strips, 0);
    for (int t = 0; t < strips; ++t) {
      std::size_t k = 0;
      while (k < seq[t].size() && seq[t][k].error <= common) ++k;
      keep[t] = k;
    }
    for (;;) {  // k-way merge by error (stable within a strip)
      int pick = -1;
      for (int t = 0; t < strips; ++t)
        if (at[t] < keep[t] && (pick < 0 || seq[t][at[t]].error < seq[pick][at[pick]].error)) pick = t;
      if (pick < 0) break;
      collapses.push_back(seq[pick][at[pick]++]);
    }
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
    Builder b(hf, options);
    b.init_faces(faces);
    b.run(collapses, quantum, 0, progress, /*report=*/true);
  }
  if (options.progress) options.progress(1.0);
  return from_parts(hf, options.metric, quantum, std::move(collapses), std::move(dropped));
}

}  // namespace terralod::pm
