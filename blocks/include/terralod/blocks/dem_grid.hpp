// What a DEM is (DemGrid) and the one interface its samples are read through, window by window
// (DemSource), with the source over a grid held in memory; open_dem_source (dem_source.hpp) opens
// a file as one. Apart from the readers so that the frames' warp (a DemSource over another) sits
// below read_dem, which warps through it.
//
// Usage:
//   #include <terralod/blocks/dem_grid.hpp>
//   auto mem = terralod::blocks::heightfield_source(hf);     // hf: a pm::Heightfield
//   pm::Heightfield b = mem->read({0, 0, 256, 256});         // its first block
//
// The DemSource contract is dem_source.hpp's.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "terralod/blocks/sample_rect.hpp"
#include "terralod/pm/heightfield.hpp"

namespace terralod::blocks {

/// What a DEM is, without its samples: the fields of pm::Heightfield that describe the grid.
struct DemGrid {
  int width = 0, height = 0;
  pm::GridTransform transform;                     ///< sample (col, row) -> world metres
  std::string crs_wkt;                             ///< Heightfield::crs_wkt
  std::optional<pm::GridTransform> crs_transform;  ///< Heightfield::crs_transform
  std::string vertical_datum;                      ///< Heightfield::vertical_datum
  std::string source;                              ///< Heightfield::source
  std::string frame;                               ///< Heightfield::frame
  std::optional<double> scale_error;               ///< frame_scale_error of the DEM (dem_reader.hpp)
  /// The samples are the input's resampled to the frame's grid (--crs auto or a named CRS), not
  /// the input's own.
  bool warped = false;

  /// The grid of `hf` (its samples left out; scale_error = frame_scale_error(hf)).
  static DemGrid of(const pm::Heightfield& hf);
  /// Samples in the grid.
  std::uint64_t samples() const { return std::uint64_t(width) * std::uint64_t(height); }
};

class DemSource {
 public:
  virtual ~DemSource() = default;
  const DemGrid& grid() const { return grid_; }
  /// Names the input as the database records it (DemInputs::description()).
  void set_source(std::string source) { grid_.source = std::move(source); }
  /// The samples of `window` (see the header comment).
  virtual pm::Heightfield read(SampleRect window) const = 0;
  /// read(window), and in file_voids the window's void samples in the file, filled ones included,
  /// where the window is read from a file in the DEM's own grid (open_dem_source in the native
  /// frame, or an auto frame that keeps it); 0 for a grid in memory (its voids were filled when
  /// it was read) and for a warped frame's cells. One read, where counting on a second source
  /// that keeps voids read the file twice.
  virtual pm::Heightfield read_counting_voids(SampleRect window, std::size_t& file_voids) const {
    file_voids = 0;
    return read(window);
  }
  /// CRC-32 of the samples and mask (see the header comment).
  virtual std::uint32_t samples_crc() const = 0;
  /// Whether the whole grid is in memory.
  virtual bool in_memory() const = 0;
  /// false only when `window` is known to hold no valid sample without reading its samples (a
  /// grid in memory: its mask; a GDAL raster with a nodata value: the driver's data coverage,
  /// such as a VRT mosaic with no tile there); true otherwise. A covered window may still be all
  /// voids. --crs auto chooses its projection over the covered part of the footprint.
  virtual bool may_have_data(SampleRect window) const {
    (void)window;
    return true;
  }
  /// The largest void region (bounding box, in samples) that read() fills: a region of empty
  /// windows smaller than this still reads as samples. 0 when voids stay holes (kept, or
  /// already filled in a grid held in memory).
  virtual std::size_t filled_void_cells() const { return 0; }
  /// What read() has done so far to fill voids: regions solved (a region solved again by a later
  /// read counts again) and their samples, and regions whose values a read took from an earlier
  /// read instead (windowed sources keep large filled regions; see open_dem_source). All zero
  /// for a grid in memory, whose voids were filled when it was read.
  struct VoidFillWork {
    std::size_t solved = 0, solved_samples = 0, reused = 0;
  };
  virtual VoidFillWork void_fill_work() const { return {}; }

 protected:
  /// Throws std::invalid_argument naming `name` unless `window` is a window of the grid.
  void check_window(SampleRect window, const std::string& name) const;
  /// Gives `b`, the samples of `window`, what read() promises besides them: the grid's transform
  /// moved to the window's first sample, its crs_wkt, source and frame.
  void describe(pm::Heightfield& b, SampleRect window) const;

  DemGrid grid_;
};

/// A DemSource over `hf`, which must outlive it (no copy is made).
std::unique_ptr<DemSource> heightfield_source(const pm::Heightfield& hf);
/// A DemSource that owns `hf`.
std::unique_ptr<DemSource> heightfield_source(pm::Heightfield&& hf);

/// The worst relative scale error of hf's world frame against its CRS's ellipsoid: the largest
/// |sigma - 1| over the singular values sigma of the map (east, north metres on the ellipsoid)
/// -> world metres, at a 33 x 33 lattice of valid samples and at both ends of every row of
/// valid samples. Distances measured in the world frame are true to within this fraction
/// (locally; along any path of valid samples). nullopt when hf has no CRS (or PROJ cannot
/// place it). Costs a few milliseconds.
std::optional<double> frame_scale_error(const pm::Heightfield& hf);

}  // namespace terralod::blocks
