// DemSource over a Heightfield in memory, and DemGrid::of (dem_source.hpp). The windowed GDAL
// source lives beside the readers it shares code with (dem_windows.cpp).
#include "terralod/blocks/dem_source.hpp"

#include <cstdint>
#include <span>

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

namespace {

class HeightfieldSource final : public DemSource {
 public:
  explicit HeightfieldSource(const pm::Heightfield& hf) : hf_(hf) { grid_ = DemGrid::of(hf); }
  pm::Heightfield read(SampleRect window) const override { return block_heightfield(hf_, window); }
  std::uint32_t samples_crc() const override {
    const auto& z = hf_.samples();
    const std::uint32_t crc =
        pm::crc32_of({reinterpret_cast<const std::uint8_t*>(z.data()), z.size() * sizeof(double)});
    const auto& m = hf_.mask();
    return m.empty() ? crc : pm::crc32_of(m, crc);
  }
  bool in_memory() const override { return true; }

 private:
  const pm::Heightfield& hf_;
};

}  // namespace

std::unique_ptr<DemSource> heightfield_source(const pm::Heightfield& hf) {
  return std::make_unique<HeightfieldSource>(hf);
}

}  // namespace terralod::blocks
