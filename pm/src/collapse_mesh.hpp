// Private to the PM builder (pm_builder.cpp): OpenMesh's triangle mesh with every vertex's ring
// in one cache line, and the builder's mesh operations (add a face, collapse a halfedge, the
// link condition, compaction) written against the kernel's inline accessors.
//
// Each operation leaves exactly the connectivity OpenMesh's own would (the same elements, links
// and outgoing halfedges), so ring walks, and with them every tie-break of the builder, see the
// mesh they would see through OpenMesh; the PM does not depend on which one ran. Memory:
// OpenMesh's connectivity (~180 bytes per vertex) and a 64-byte Ring per vertex.
#pragma once

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <algorithm>
#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>
#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "huge_vector.hpp"

namespace terralod::pm::detail {
namespace {  // one translation unit (pm_builder.cpp): internal linkage, as when the code lived there

struct MeshTraits : OpenMesh::DefaultTraits {
  VertexAttributes(OpenMesh::Attributes::Status);
  EdgeAttributes(OpenMesh::Attributes::Status);
  FaceAttributes(OpenMesh::Attributes::Status);
  HalfedgeAttributes(OpenMesh::Attributes::PrevHalfedge);
};
using Mesh = OpenMesh::TriMesh_ArrayKernelT<MeshTraits>;

class CollapseMesh : public Mesh {
 public:
  // Reserves the mesh and adds nv vertices. OpenMesh's element and property arrays are the
  // largest, most randomly accessed memory of the build (the halfedges alone ~100 bytes per
  // vertex): they are advised to use transparent huge pages before their pages are touched
  // (reserve() only allocates), so that ring walks at random places do not also miss the TLB.
  void init_vertices(std::size_t nv, std::size_t n_edges, std::size_t n_faces) {
    reserve(nv, n_edges, n_faces);
    const auto v0 = add_vertex(Mesh::Point(0, 0, 0));
    advise_huge(&vertex(v0), nv * sizeof(Mesh::Vertex));
    advise_huge(&point(v0), nv * sizeof(Mesh::Point));
    advise_huge(&status(v0), nv * sizeof(OpenMesh::Attributes::StatusInfo));
    for (std::size_t i = 1; i < nv; ++i) add_vertex(Mesh::Point(0, 0, 0));
    reserved_edges_ = n_edges, reserved_faces_ = n_faces;
  }

  // add_face of a triangle; the edge and face arrays are advised once the first face made them
  // reachable (the pages of their first 2 MiB are not advised, the rest is still untouched).
  Mesh::FaceHandle add_triangle(const std::vector<Mesh::VertexHandle>& tri) {
    const auto f = connect_triangle(tri.data());
    if (f.is_valid() && n_faces() == 1) {
      const auto e0 = Mesh::EdgeHandle(0);
      advise_huge(&edge(e0), reserved_edges_ * sizeof(Mesh::Edge));
      advise_huge(&status(e0), reserved_edges_ * sizeof(OpenMesh::Attributes::StatusInfo));
      advise_huge(&face(f), reserved_faces_ * sizeof(Mesh::Face));
      advise_huge(&status(f), reserved_faces_ * sizeof(OpenMesh::Attributes::StatusInfo));
    }
    return f;
  }

  // Every vertex's outgoing halfedges, in the order for_each_outgoing visits them, in one
  // cache line. Walking a ring through OpenMesh is a chain of dependent loads (each halfedge
  // names the next), one cache miss after another at a random place of the mesh: from the
  // record, the CPU issues all of the ring's loads at once. Only a collapse changes rings,
  // and only those of w and of the two wing vertices (see collapse_halfedge): the other
  // neighbours of u keep their halfedges, now pointing at w, in the same order. Degrees above
  // kRingCap (1 in 2000 evaluations on N44W072) are walked through OpenMesh.
  static constexpr std::uint32_t kRingCap = 15;
  struct alignas(64) Ring {
    std::uint32_t h[kRingCap];
    std::uint32_t n;  // the degree; the halfedges are stored when n <= kRingCap
  };
  static_assert(sizeof(Ring) == 64);
  const Ring& ring(std::uint32_t v) const { return rings_[v]; }
  void init_rings() {
    rings_.resize(n_vertices());
    for (std::uint32_t v = 0; v < n_vertices(); ++v) refresh_ring(v);
  }
  // for_each_outgoing(v, f) from v's record.
  template <class F>
  void for_each_ring(std::uint32_t v, F&& f) const {
    const Ring& r = rings_[v];
    if (r.n > kRingCap) return for_each_outgoing(Mesh::VertexHandle(int(v)), f);
    assert(ring_matches(v));
    for (std::uint32_t i = 0; i < r.n; ++i) f(Mesh::HalfedgeHandle(int(r.h[i])));
  }
  // After a collapse, the neighbours' rings are read one after the other by the builder's
  // evaluate(); this starts the loads of their halfedges at once.
  void prefetch_ring(std::uint32_t v) const {
    const Ring& r = rings_[v];
    const std::uint32_t n = std::min(r.n, kRingCap);
    for (std::uint32_t i = 0; i < n; ++i) __builtin_prefetch(&halfedge(Mesh::HalfedgeHandle(int(r.h[i]))));
  }

  // Outgoing halfedges of v, calling f(h) for each. Hand-written with the kernel's inline
  // accessors: OpenMesh's circulators validate every handle through a library call.
  template <class F>
  void for_each_outgoing(Mesh::VertexHandle v, F&& f) const {
    const auto start = halfedge_handle(v);
    if (!start.is_valid()) return;
    auto h = start;
    do {
      f(h);
      h = next_halfedge_handle(opposite_halfedge_handle(h));
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
  void collapse_halfedge(Mesh::HalfedgeHandle h, const std::vector<Mesh::HalfedgeHandle>& outgoing_u) {
    const auto hn = next_halfedge_handle(h), hp = prev_halfedge_handle(h);
    const auto o = opposite_halfedge_handle(h);
    const auto on = next_halfedge_handle(o), op = prev_halfedge_handle(o);
    const auto fh = face_handle(h), fo = face_handle(o);
    const auto vw = to_vertex_handle(h), vu = to_vertex_handle(o);
    const auto wing_h = fh.is_valid() ? to_vertex_handle(hn) : Mesh::VertexHandle();
    const auto wing_o = fo.is_valid() ? to_vertex_handle(on) : Mesh::VertexHandle();
    // adjust_outgoing() looks for a boundary halfedge and finds none around an interior
    // vertex; the collapse of an interior edge makes no vertex a boundary one, so the walks
    // are skipped for the vertices that are interior now (a boundary vertex's outgoing
    // halfedge is a boundary one).
    const auto if_interior = [&](Mesh::VertexHandle v) {
      return v.is_valid() && !is_boundary(halfedge_handle(v)) ? v : Mesh::VertexHandle();
    };
    const Interior interior = {if_interior(vw), if_interior(wing_h), if_interior(wing_o)};
    for (const auto g : outgoing_u) set_vertex_handle(opposite_halfedge_handle(g), vw);
    set_next_halfedge_handle(hp, hn);
    set_next_halfedge_handle(op, on);
    if (fh.is_valid()) set_halfedge_handle(fh, hn);
    if (fo.is_valid()) set_halfedge_handle(fo, on);
    if (halfedge_handle(vw) == o) set_halfedge_handle(vw, hn);
    if (!is_interior(vw, interior)) adjust_outgoing(vw);
    set_isolated(vu);
    status(edge_handle(h)).set_deleted(true);
    status(vu).set_deleted(true);
    if (next_halfedge_handle(next_halfedge_handle(hn)) == hn) remove_loop(next_halfedge_handle(hn), interior);
    if (next_halfedge_handle(next_halfedge_handle(on)) == on) remove_loop(on, interior);
    // The rings that changed (see Ring).
    rings_[std::uint32_t(vu.idx())].n = 0;
    refresh_ring(std::uint32_t(vw.idx()));
    if (wing_h.is_valid()) refresh_ring(std::uint32_t(wing_h.idx()));
    if (wing_o.is_valid()) refresh_ring(std::uint32_t(wing_o.idx()));
  }

  // Topological legality of collapsing halfedge h (u -> w), the link condition of Dey et al.
  // as OpenMesh's is_collapse_ok checks it, without its per-call allocations: the common
  // neighbours of u and w are exactly the opposite vertices of the faces beside the edge, and
  // an interior edge may not join two boundary vertices.
  // ring_u: the heads of u's outgoing halfedges.
  bool link_ok(Mesh::HalfedgeHandle h, const std::vector<std::uint32_t>& ring_u) const {
    const auto vu = from_vertex_handle(h), vw = to_vertex_handle(h);
    const auto o = opposite_halfedge_handle(h);
    const bool edge_boundary = is_boundary(h) || is_boundary(o);
    if (!edge_boundary && is_boundary(vu) && is_boundary(vw)) return false;
    std::uint32_t wings[2] = {UINT32_MAX, UINT32_MAX};
    if (!is_boundary(h)) wings[0] = std::uint32_t(to_vertex_handle(next_halfedge_handle(h)).idx());
    if (!is_boundary(o)) wings[1] = std::uint32_t(to_vertex_handle(next_halfedge_handle(o)).idx());
    if (wings[0] == wings[1]) return false;
    // Common neighbours by comparing the two (short) rings: no per-vertex marks to miss in cache.
    int common = 0;
    bool ok = true;
    for_each_ring(std::uint32_t(vw.idx()), [&](Mesh::HalfedgeHandle g) {
      const std::uint32_t x = std::uint32_t(to_vertex_handle(g).idx());
      if (std::find(ring_u.begin(), ring_u.end(), x) == ring_u.end()) return;
      if (x != wings[0] && x != wings[1]) ok = false;
      ++common;
    });
    return ok && common == (wings[0] != UINT32_MAX) + (wings[1] != UINT32_MAX);
  }

  // Collapses leave their deleted vertices, edges and faces in every array, so the live data
  // of a region thins out: a ring spreads over more cache lines, and the memory a loop reads
  // at random stays as large as at the start while the mesh shrinks. compact() moves the live
  // elements down in place, keeping their order: every tie-break by vertex id, every ring's
  // order stay. The caller's own per-vertex and per-edge arrays move with them:
  // move_vertex(from, to) and move_edge(from, to) are called for every live element, in
  // increasing `from` (to <= from), while new_vertex_id() already gives every vertex's new id.
  template <class MoveVertex, class MoveEdge>
  void compact(MoveVertex&& move_vertex, MoveEdge&& move_edge) {
    const std::uint32_t nv = std::uint32_t(n_vertices()), ne = std::uint32_t(n_edges()),
                        nf = std::uint32_t(n_faces());
    // Old -> new ids, UINT32_MAX: deleted. Kept between calls: fresh pages cost page faults.
    auto &vmap = vmap_, &emap = emap_, &fmap = fmap_;
    vmap.resize(nv), emap.resize(ne), fmap.resize(nf);
    std::uint32_t lv = 0, le = 0, lf = 0;
    for (std::uint32_t v = 0; v < nv; ++v)
      vmap[v] = status(Mesh::VertexHandle(int(v))).deleted() ? UINT32_MAX : lv++;
    for (std::uint32_t e = 0; e < ne; ++e)
      emap[e] = status(Mesh::EdgeHandle(int(e))).deleted() ? UINT32_MAX : le++;
    for (std::uint32_t f = 0; f < nf; ++f)
      fmap[f] = status(Mesh::FaceHandle(int(f))).deleted() ? UINT32_MAX : lf++;
    const auto mh = [&](Mesh::HalfedgeHandle h) {  // a live halfedge's new id
      if (!h.is_valid()) return h;
      const std::uint32_t i = std::uint32_t(h.idx());
      return Mesh::HalfedgeHandle(int(2 * emap[i >> 1] + (i & 1)));
    };
    // Element k moves to map[k] <= k, in increasing k, so nothing is overwritten before it is read.
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (vmap[v] == UINT32_MAX) continue;
      const auto vh = Mesh::VertexHandle(int(v)), vj = Mesh::VertexHandle(int(vmap[v]));
      set_halfedge_handle(vj, mh(halfedge_handle(vh)));
      status(vj) = status(vh);
      move_vertex(v, vmap[v]);
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
        const auto to = to_vertex_handle(h);
        const auto next = next_halfedge_handle(h);
        const auto f = face_handle(h);
        set_vertex_handle(hj, Mesh::VertexHandle(int(vmap[std::uint32_t(to.idx())])));
        set_face_handle(hj, f.is_valid() ? Mesh::FaceHandle(int(fmap[std::uint32_t(f.idx())])) : f);
        set_next_halfedge_handle(hj, mh(next));
      }
      status(Mesh::EdgeHandle(int(emap[e]))) = status(Mesh::EdgeHandle(int(e)));
      move_edge(e, emap[e]);
    }
    for (std::uint32_t f = 0; f < nf; ++f) {
      if (fmap[f] == UINT32_MAX) continue;
      const auto fh = Mesh::FaceHandle(int(f)), fj = Mesh::FaceHandle(int(fmap[f]));
      set_halfedge_handle(fj, mh(halfedge_handle(fh)));
      status(fj) = status(fh);
    }
    resize(lv, le, lf);
    rings_.resize(lv);
  }
  // During and after compact(): the new id of vertex v (UINT32_MAX: deleted).
  std::uint32_t new_vertex_id(std::uint32_t v) const { return vmap_[v]; }
  // Every vertex's new id, as new_vertex_id() gives them.
  const HugeVector<std::uint32_t>& new_vertex_ids() const { return vmap_; }

 private:
  // PolyConnectivity::add_face for a triangle, step for step the same algorithm (so the same
  // edges, in the same order, the same links and outgoing halfedges: the PM does not change),
  // written against the kernel's inline accessors. OpenMesh's goes through library calls that
  // check every handle, and creating the grid's 1.4 M faces per strip through it took a tenth
  // of the strip's build. The cases that change nothing here and go to OpenMesh instead: a
  // face that would make a vertex or an edge non-manifold (OpenMesh reports it and refuses),
  // and one whose existing edges first need a patch of faces re-linked around a vertex.
  Mesh::FaceHandle connect_triangle(const Mesh::VertexHandle* v) {
    Mesh::HalfedgeHandle he[3];
    bool is_new[3], adjust[3] = {false, false, false};
    for (int i = 0; i < 3; ++i) {
      const Mesh::VertexHandle from = v[i], to = v[(i + 1) % 3];
      const auto out = halfedge_handle(from);
      if (out.is_valid() && !is_boundary(out)) return add_face(v, 3);  // not a boundary vertex
      he[i] = find_outgoing(from, to);
      is_new[i] = !he[i].is_valid();
      if (!is_new[i] && !is_boundary(he[i])) return add_face(v, 3);  // the edge has two faces
    }
    for (int i = 0; i < 3; ++i) {
      const int ii = (i + 1) % 3;
      if (!is_new[i] && !is_new[ii] && next_halfedge_handle(he[i]) != he[ii]) return add_face(v, 3);
    }
    for (int i = 0; i < 3; ++i)
      if (is_new[i]) he[i] = new_edge(v[i], v[(i + 1) % 3]);
    const auto fh = new_face();
    set_halfedge_handle(fh, he[2]);
    std::pair<Mesh::HalfedgeHandle, Mesh::HalfedgeHandle> links[9];
    int n_links = 0;
    for (int i = 0; i < 3; ++i) {
      const int ii = (i + 1) % 3;
      const Mesh::VertexHandle vh = v[ii];
      const auto inner_prev = he[i], inner_next = he[ii];
      if (is_new[i] || is_new[ii]) {
        const auto outer_prev = opposite_halfedge_handle(inner_next);
        const auto outer_next = opposite_halfedge_handle(inner_prev);
        if (is_new[i] && !is_new[ii]) {
          links[n_links++] = {prev_halfedge_handle(inner_next), outer_next};
          set_halfedge_handle(vh, outer_next);
        } else if (!is_new[i]) {
          const auto boundary_next = next_halfedge_handle(inner_prev);
          links[n_links++] = {outer_prev, boundary_next};
          set_halfedge_handle(vh, boundary_next);
        } else if (!halfedge_handle(vh).is_valid()) {
          set_halfedge_handle(vh, outer_next);
          links[n_links++] = {outer_prev, outer_next};
        } else {
          const auto boundary_next = halfedge_handle(vh);
          links[n_links++] = {prev_halfedge_handle(boundary_next), outer_next};
          links[n_links++] = {outer_prev, boundary_next};
        }
        links[n_links++] = {inner_prev, inner_next};
      } else {
        adjust[ii] = halfedge_handle(vh) == inner_next;
      }
      set_face_handle(he[i], fh);
    }
    for (int i = 0; i < n_links; ++i) set_next_halfedge_handle(links[i].first, links[i].second);
    for (int i = 0; i < 3; ++i)
      if (adjust[i]) adjust_outgoing(v[i]);
    return fh;
  }

  Mesh::HalfedgeHandle find_outgoing(Mesh::VertexHandle from, Mesh::VertexHandle to) const {
    Mesh::HalfedgeHandle found;
    for_each_outgoing(from, [&](Mesh::HalfedgeHandle h) {
      if (to_vertex_handle(h) == to) found = h;
    });
    return found;
  }

  static void advise_huge([[maybe_unused]] const void* p, [[maybe_unused]] std::size_t bytes) {
#ifdef MADV_HUGEPAGE
    constexpr std::uintptr_t kHuge = std::uintptr_t(2) << 20;
    const std::uintptr_t begin = (std::uintptr_t(p) + kHuge - 1) & ~(kHuge - 1);
    const std::uintptr_t end = (std::uintptr_t(p) + bytes) & ~(kHuge - 1);
    if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);  // advice only
#endif
  }

  void refresh_ring(std::uint32_t v) {
    Ring& r = rings_[v];
    std::uint32_t n = 0;
    for_each_outgoing(Mesh::VertexHandle(int(v)), [&](Mesh::HalfedgeHandle h) {
      if (n < kRingCap) r.h[n] = std::uint32_t(h.idx());
      ++n;
    });
    r.n = n;
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

  // collapse_halfedge(): w and the wings, each where it is an interior vertex, else invalid.
  using Interior = std::array<Mesh::VertexHandle, 3>;
  static bool is_interior(Mesh::VertexHandle v, const Interior& interior) {
    return v.is_valid() && (v == interior[0] || v == interior[1] || v == interior[2]);
  }

  // Removes the loop of two halfedges h0, next(h0) that a collapse left: h0's edge goes, and
  // next(h0) takes the place of h0's opposite in the face on the other side.
  void remove_loop(Mesh::HalfedgeHandle h0, const Interior& interior) {
    const auto h1 = next_halfedge_handle(h0);
    const auto o0 = opposite_halfedge_handle(h0), o1 = opposite_halfedge_handle(h1);
    const auto v0 = to_vertex_handle(h0), v1 = to_vertex_handle(h1);
    const auto fh = face_handle(h0), fo = face_handle(o0);
    assert(next_halfedge_handle(h1) == h0 && h1 != o0);
    set_next_halfedge_handle(h1, next_halfedge_handle(o0));
    set_next_halfedge_handle(prev_halfedge_handle(o0), h1);
    set_face_handle(h1, fo);
    set_halfedge_handle(v0, h1);
    if (!is_interior(v0, interior)) adjust_outgoing(v0);
    set_halfedge_handle(v1, o1);
    if (!is_interior(v1, interior)) adjust_outgoing(v1);
    if (fo.is_valid() && halfedge_handle(fo) == o0) set_halfedge_handle(fo, h1);
    if (fh.is_valid()) {
      set_halfedge_handle(fh, Mesh::HalfedgeHandle());
      status(fh).set_deleted(true);
    }
    status(edge_handle(h0)).set_deleted(true);
  }

  // Makes v's outgoing halfedge its first boundary one in clockwise order from the current
  // one, if it has any (OpenMesh's convention, which boundary tests rely on).
  void adjust_outgoing(Mesh::VertexHandle v) {
    const auto start = halfedge_handle(v);
    if (!start.is_valid()) return;
    auto h = start;
    do {
      if (is_boundary(h)) {
        set_halfedge_handle(v, h);
        return;
      }
      h = next_halfedge_handle(opposite_halfedge_handle(h));
    } while (h != start);
  }

  HugeVector<Ring> rings_;                        // by vertex id
  HugeVector<std::uint32_t> vmap_, emap_, fmap_;  // compact()'s maps
  std::size_t reserved_edges_ = 0, reserved_faces_ = 0;
};

}  // namespace
}  // namespace terralod::pm::detail
