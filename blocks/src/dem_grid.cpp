// DemSource over a Heightfield in memory, and DemGrid::of (dem_grid.hpp). The windowed GDAL
// source lives beside the readers it shares code with (dem_windows.cpp); frame_scale_error beside
// the scale error it measures through (frame_scale.cpp).
#include "terralod/blocks/dem_grid.hpp"

#include <cstdint>
#include <span>
#include <stdexcept>
#include <tuple>

#include "terralod/blocks/partition.hpp"
#include "terralod/pm/byte_io.hpp"

namespace terralod::blocks {

DemGrid DemGrid::of(const pm::Heightfield& hf) {
  DemGrid g;
  g.width = hf.width();
  g.height = hf.height();
  g.transform = hf.transform;
  g.crs_wkt = hf.crs_wkt;
  g.crs_transform = hf.crs_transform;
  g.vertical_datum = hf.vertical_datum;
  g.source = hf.source;
  g.frame = hf.frame;
  g.scale_error = frame_scale_error(hf);
  return g;
}

void DemSource::check_window(SampleRect window, const std::string& name) const {
  if (window.col0 < 0 || window.row0 < 0 || window.col1 >= grid_.width || window.row1 >= grid_.height ||
      window.col0 > window.col1 || window.row0 > window.row1)
    throw std::invalid_argument(name + ": window outside the grid");
}

void DemSource::describe(pm::Heightfield& b, SampleRect window) const {
  b.transform = grid_.transform;
  std::tie(b.transform.x0, b.transform.y0) = grid_.transform.to_world(window.col0, window.row0);
  b.crs_wkt = grid_.crs_wkt;
  b.source = grid_.source;
  b.frame = grid_.frame;
}

namespace {

/// Serves `hf`, or the grid it owns when given one to keep (`owned`).
class HeightfieldSource final : public DemSource {
 public:
  explicit HeightfieldSource(const pm::Heightfield& hf) : hf_(hf) { grid_ = DemGrid::of(hf); }
  explicit HeightfieldSource(pm::Heightfield&& hf) : owned_(std::move(hf)), hf_(owned_) {
    grid_ = DemGrid::of(hf_);
  }
  /// block_heightfield's samples, named after the grid's source (set_source may rename it).
  pm::Heightfield read(SampleRect window) const override {
    pm::Heightfield b = block_heightfield(hf_, window);
    b.source = grid_.source;
    return b;
  }
  std::uint32_t samples_crc() const override {
    const auto& z = hf_.samples();
    const std::uint32_t crc =
        pm::crc32_of({reinterpret_cast<const std::uint8_t*>(z.data()), z.size() * sizeof(double)});
    const auto& m = hf_.mask();
    return m.empty() ? crc : pm::crc32_of(m, crc);
  }
  bool in_memory() const override { return true; }
  bool may_have_data(SampleRect window) const override {
    if (!hf_.has_holes()) return true;
    for (int r = window.row0; r <= window.row1; ++r)
      for (int c = window.col0; c <= window.col1; ++c)
        if (hf_.valid(c, r)) return true;
    return false;
  }

 private:
  pm::Heightfield owned_;  ///< empty unless this source owns its grid
  const pm::Heightfield& hf_;
};

}  // namespace

std::unique_ptr<DemSource> heightfield_source(const pm::Heightfield& hf) {
  return std::make_unique<HeightfieldSource>(hf);
}

std::unique_ptr<DemSource> heightfield_source(pm::Heightfield&& hf) {
  return std::make_unique<HeightfieldSource>(std::move(hf));
}

}  // namespace terralod::blocks
