// The reference PM build through OpenMesh's DecimaterT and ModLInfT, recording every collapse
// (openmesh_build.hpp). Paper: seeds/view-dependent-pm-dynamic-loading.txt, section 2, Eq. 1,
// as ProgressiveMesh::build. Memory: see the header.
#include "terralod/pm/openmesh_build.hpp"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/Observer.hh>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "grid_mesh.hpp"
#include "terralod/pm/linf_decimater_module.hpp"

namespace terralod::pm {
namespace {

using Mesh = OpenMesh::TriMesh_ArrayKernelT<>;

// ModLInfT that also records every collapse DecimaterT performs. DecimaterT calls
// preprocess_collapse(ci) just before mesh.collapse(ci.v0v1), on the mesh the collapse was
// ranked on (a vertex is ranked again whenever its ring changes), so collapse_error(ci) is the
// error of the collapse that is performed.
template <class MeshT>
class ModLInfRecordT : public ModLInfT<MeshT> {
 public:
  DECIMATING_MODULE(ModLInfRecordT, MeshT, LInfRecord);

  explicit ModLInfRecordT(MeshT& mesh) : ModLInfT<MeshT>(mesh) {}

  /// Where the collapses go; sample_of[v] is vertex v's sample; errors rounded up to `quantum`.
  void record_into(std::vector<Collapse>& out, const std::vector<std::uint32_t>& sample_of, double quantum) {
    out_ = &out;
    sample_of_ = &sample_of;
    quantum_ = quantum;
  }

  void preprocess_collapse(const CollapseInfo& ci) override {
    const double e = this->collapse_error(ci);
    if (e < 0.0)  // DecimaterT performs only collapses the module ranked legal
      throw std::logic_error("build_with_decimater: DecimaterT performs a collapse ModLInfT ranks illegal");
    out_->push_back(Collapse{(*sample_of_)[std::size_t(ci.v0.idx())], (*sample_of_)[std::size_t(ci.v1.idx())],
                             std::ceil(e / quantum_) * quantum_});
  }

 private:
  std::vector<Collapse>* out_ = nullptr;
  const std::vector<std::uint32_t>* sample_of_ = nullptr;
  double quantum_ = 1.0;
};

// BuildOptions::progress through OpenMesh's Observer: DecimaterT calls notify() every
// `interval` collapses and stops when abort() says so.
class ProgressObserver : public OpenMesh::Decimater::Observer {
 public:
  ProgressObserver(const ProgressFn& progress, std::size_t total)
      : Observer(std::max<std::size_t>(1, total / 64)),
        progress_(progress),
        total_(std::max<std::size_t>(1, total)) {}
  void notify(std::size_t step) override {
    if (!progress_(std::min(1.0, double(step) / double(total_)))) cancelled_ = true;
  }
  bool abort() const override { return cancelled_; }
  bool cancelled() const { return cancelled_; }

 private:
  const ProgressFn& progress_;
  std::size_t total_;
  bool cancelled_ = false;
};

}  // namespace

ProgressiveMesh build_with_decimater(const Heightfield& hf, const BuildOptions& options) {
  detail::check_buildable(hf);
  const double quantum = ProgressiveMesh::error_quantum_for(hf);
  const int W = hf.width();

  // One vertex per valid sample, then the faces as the builder adds them (grid_mesh.hpp).
  Mesh mesh;
  std::vector<Mesh::VertexHandle> vertex_of(hf.size());
  std::vector<std::uint32_t> sample_of;
  std::size_t valid = 0;
  for (std::size_t s = 0; s < hf.size(); ++s) valid += hf.valid(s);
  mesh.reserve(valid, 3 * valid, 2 * valid);
  sample_of.reserve(valid);
  for (std::uint32_t s = 0; s < hf.size(); ++s) {
    if (!hf.valid(s)) continue;
    vertex_of[s] =
        mesh.add_vertex(Mesh::Point(float(s % std::uint32_t(W)), float(s / std::uint32_t(W)), float(hf[s])));
    sample_of.push_back(s);
  }
  std::vector<std::uint32_t> dropped;
  std::vector<Mesh::VertexHandle> tri(3);
  detail::add_faces_row_by_row(
      hf, 0, W - 1,
      [&](const std::uint32_t(&samples)[3], const GridPoint(&)[3]) {
        for (int c = 0; c < 3; ++c) tri[std::size_t(c)] = vertex_of[samples[c]];
        return mesh.add_face(tri).is_valid();
      },
      dropped);

  using Module = ModLInfRecordT<Mesh>;
  std::vector<Collapse> collapses;
  collapses.reserve(valid);
  {
    OpenMesh::Decimater::DecimaterT<Mesh> decimater(mesh);
    Module::Handle h;
    if (!decimater.add(h)) throw std::logic_error("build_with_decimater: DecimaterT refused ModLInfT");
    Module& module = decimater.module(h);
    module.set_heightfield(hf, options.metric);
    module.set_max_error(options.max_error, /*binary=*/false);
    module.record_into(collapses, sample_of, quantum);
    if (!decimater.initialize())
      throw std::logic_error("build_with_decimater: DecimaterT found no priority module");
    ProgressObserver observer(options.progress, valid > 4 ? valid - 4 : 1);
    if (options.progress) decimater.set_observer(&observer);
    decimater.decimate();
    decimater.set_observer(nullptr);
    if (observer.cancelled()) throw std::runtime_error("progressive mesh build cancelled");
  }
  if (options.progress) options.progress(1.0);
  return ProgressiveMesh::from_parts(hf, options.metric, quantum, std::move(collapses), std::move(dropped));
}

}  // namespace terralod::pm
