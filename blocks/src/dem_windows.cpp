// open_dem_source (dem_source.hpp): DemSources that read a GDAL raster or an SRTM .hgt tile window
// by window, through the header, georeference and sample code of read_dem (dem_raster.hpp),
// under a warped source (dem_frame.hpp) when the frame warps; heightmap images and ASCII grids,
// which can only be read from their first row on, through a temporary file they are decoded to
// once (DecodedSource).
//
// read(window): the window's raw samples, then fill_voids_in_window; while a void region that
// meets the window is cut by the window's edge (VoidFillStats::open), the window grows to hold
// a ring past each window edge that region touches (16 samples, doubling at each step, cut by
// the grid) and is read again. Regions are filled alone on their own box (void_fill.hpp), so the
// bits are those of read_dem's whole-grid fill; regions over VoidFillOptions::max_region_cells
// are capped as soon as the part seen is over the cap, and stay holes, as in read_dem. Cost: a
// read meeting such a region (a nodata collar around a mosaic's coverage, say) holds more than
// 4096 x 4096 samples before it knows; the source then remembers that region's void samples (as
// runs along rows), so a later read that meets a known part of it stops growing there. Filled
// regions of FilledVoids::kKeepFrom samples or more are kept with their values (FilledVoids), and
// a later read takes them before filling, so a wide gap is solved once, not by every read.
// Thread-safety: GDAL datasets are not: each read takes an opened dataset from a pool (opening
// another when all are busy) and gives it back; the fill runs on the caller's thread. .hgt
// windows are read with a stream opened per read, so a file removed or truncated after opening
// gives a DemError from read(), not stale samples (a GDAL source checks that its file still exists).
// GDAL's block cache: unless the process set GDAL_CACHEMAX (environment or config option), it is
// capped to 64 MiB while a windowed source is open (GDAL's default, 5 % of RAM, would grow with
// the DEM) and restored when the last one closes.
// samples_crc streams bands of whole rows (about 4 Mi samples each) through read(): one running
// CRC of the samples, one of the mask bytes (1 for bands without holes), joined at the end by
// zlib's crc32_combine64 when the grid has a hole: one pass, memory of one band.
// Differs from read_dem: the grid size is not limited to 2^30 samples, and a grid with no valid
// sample at all is refused (DemError, read_dem's words) only by a read that grows to the whole
// grid, which filling voids does (measuring the frame at open reads one); with voids kept, its
// reads give holes and build_database refuses it after its blocks.
#include <fcntl.h>
#include <gdal_priv.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>
#include <utility>
#include <vector>

#include "dem_frame.hpp"
#include "dem_raster.hpp"
#include "gdal_support.hpp"
#include "sample_crc.hpp"
#include "terralod/blocks/dem_source.hpp"
#include "terralod/blocks/void_fill.hpp"

namespace terralod::blocks {

namespace {

namespace fs = std::filesystem;
using Format = DemOptions::Format;

/// The void samples left in `z` (the samples of `held`), one 4-connected region at a time: its
/// bounding box in grid coordinates and its samples as runs along rows.
std::vector<std::pair<SampleRect, SampleRuns>> void_regions(const std::vector<double>& z, SampleRect held) {
  const int w = held.width(), h = held.height();
  std::vector<std::uint8_t> seen(z.size(), 0);
  std::vector<std::pair<SampleRect, SampleRuns>> out;
  std::vector<std::uint32_t> stack, cells;
  for (std::size_t start = 0; start < z.size(); ++start) {
    if (seen[start] || std::isfinite(z[start])) continue;
    cells.clear();
    stack.assign(1, std::uint32_t(start));
    seen[start] = 1;
    while (!stack.empty()) {
      const std::uint32_t k = stack.back();
      stack.pop_back();
      cells.push_back(k);
      const int c = int(k % std::uint32_t(w)), r = int(k / std::uint32_t(w));
      auto visit = [&](int cc, int rr) {
        const std::size_t n = std::size_t(rr) * std::size_t(w) + std::size_t(cc);
        if (cc >= 0 && rr >= 0 && cc < w && rr < h && !seen[n] && !std::isfinite(z[n]))
          seen[n] = 1, stack.push_back(std::uint32_t(n));
      };
      visit(c - 1, r), visit(c + 1, r), visit(c, r - 1), visit(c, r + 1);
    }
    std::sort(cells.begin(), cells.end());
    SampleRuns runs = runs_of(cells, held);
    SampleRect box{held.col1, runs.front()[0], held.col0, runs.back()[0]};
    for (const auto& [r, c0, c1] : runs) box.col0 = std::min(box.col0, c0), box.col1 = std::max(box.col1, c1);
    out.emplace_back(box, std::move(runs));
  }
  return out;
}

/// Void samples of regions over the fill cap found so far: a later read whose cut region holds
/// one of them knows that region stays a hole without growing until it sees it whole.
class CappedVoids {
 public:
  bool empty() const {
    std::shared_lock lock(mutex_);
    return rows_.empty();
  }
  /// Whether any sample of `runs` is a known capped void.
  bool holds(const SampleRuns& runs) const {
    std::shared_lock lock(mutex_);
    for (const auto& [r, c0, c1] : runs) {
      const auto it = rows_.find(r);
      if (it == rows_.end()) continue;
      for (const auto& [a, b] : it->second)
        if (a <= c1 && c0 <= b) return true;
    }
    return false;
  }
  void add(const SampleRuns& runs) {
    std::unique_lock lock(mutex_);
    for (const auto& [r, c0, c1] : runs) rows_[r].emplace_back(c0, c1);
  }

 private:
  mutable std::shared_mutex mutex_;
  std::map<int, std::vector<std::pair<int, int>>> rows_;
};

/// Filled void regions of kKeepFrom samples or more, with their values, kept from the reads that
/// solved them: a later read meeting one takes its values instead of growing to hold the region
/// and solving it again. The bits are the same, since a region's values depend on its box alone
/// (void_fill.hpp). Without it, every block (and every small read that measures the frame) meeting
/// a wide gap between a mosaic's tiles solved the whole gap: a 4 x 4 degree band mosaic whose
/// gaps are three SRTM tiles each spent minutes opening. Held up to `budget` bytes
/// (DemOptions::filled_void_cache_bytes; the default holds one region of the largest size filled,
/// 128 MiB of values, and as much again), the least recently used region leaving first; a region
/// larger than that is solved by every read.
class FilledVoids {
 public:
  static constexpr std::size_t kKeepFrom = 1024;
  explicit FilledVoids(std::size_t budget) : budget_(budget) {}

  /// Writes the values of the kept regions into the void samples of z (the samples of `held`)
  /// they cover; returns how many regions gave a value.
  std::size_t apply(SampleRect held, std::vector<double>& z) const {
    std::lock_guard lock(mutex_);
    if (rows_.empty()) return 0;
    const std::size_t w = std::size_t(held.width());
    std::vector<std::uint64_t> used;
    for (auto it = rows_.lower_bound(held.row0); it != rows_.end() && it->first <= held.row1; ++it)
      for (const Ref& ref : it->second) {
        const int c0 = std::max(ref.col0, held.col0), c1 = std::min(ref.col1, held.col1);
        if (c0 > c1) continue;
        const Entry& e = regions_.at(ref.id);
        double* out = z.data() + std::size_t(it->first - held.row0) * w + std::size_t(c0 - held.col0);
        const double* in = e.region.values.data() + ref.offset + std::size_t(c0 - ref.col0);
        bool wrote = false;
        for (int c = c0; c <= c1; ++c, ++out, ++in)
          if (!std::isfinite(*out))
            *out = *in, wrote = true;  // a valid sample there (a changed file) is kept
        if (wrote && std::find(used.begin(), used.end(), ref.id) == used.end()) used.push_back(ref.id);
      }
    for (const std::uint64_t id : used) regions_.at(id).last_use = ++clock_;
    return used.size();
  }

  void add(std::vector<FilledVoidRegion>& regions) {
    std::lock_guard lock(mutex_);
    for (FilledVoidRegion& r : regions) {
      if (r.runs.empty()) continue;
      const std::size_t bytes =
          r.values.size() * sizeof(double) + r.runs.size() * (sizeof(r.runs[0]) + sizeof(Ref));
      if (bytes > budget_ || known(r.runs.front())) continue;  // too large, or another read kept it
      while (bytes_ + bytes > budget_) evict_oldest();
      const std::uint64_t id = next_id_++;
      std::size_t offset = 0;
      for (const auto& [row, c0, c1] : r.runs) {
        rows_[row].push_back(Ref{c0, c1, id, offset});
        offset += std::size_t(c1 - c0 + 1);
      }
      bytes_ += bytes;
      regions_.emplace(id, Entry{std::move(r), bytes, ++clock_});
    }
  }

 private:
  struct Entry {
    FilledVoidRegion region;
    std::size_t bytes = 0;
    std::uint64_t last_use = 0;
  };
  struct Ref {  // one run of a region, in rows_
    int col0, col1;
    std::uint64_t id;
    std::size_t offset;  // of its first value in the region's values
  };
  bool known(const SampleRuns::value_type& run) const {
    const auto it = rows_.find(run[0]);
    if (it == rows_.end()) return false;
    return std::any_of(it->second.begin(), it->second.end(),
                       [&](const Ref& ref) { return ref.col0 <= run[2] && run[1] <= ref.col1; });
  }
  void evict_oldest() {
    const auto oldest = std::min_element(regions_.begin(), regions_.end(), [](const auto& a, const auto& b) {
      return a.second.last_use < b.second.last_use;
    });
    for (const auto& run : oldest->second.region.runs) {
      auto it = rows_.find(run[0]);
      std::erase_if(it->second, [&](const Ref& ref) { return ref.id == oldest->first; });
      if (it->second.empty()) rows_.erase(it);
    }
    bytes_ -= oldest->second.bytes;
    regions_.erase(oldest);
  }

  std::size_t budget_;
  mutable std::mutex mutex_;
  mutable std::map<std::uint64_t, Entry> regions_;  // by id
  std::map<int, std::vector<Ref>> rows_;            // runs by row
  std::uint64_t next_id_ = 0;
  mutable std::uint64_t clock_ = 0;
  std::size_t bytes_ = 0;
};

/// A DemSource that reads raw windows (raw()) and fills their voids as read_dem does.
class WindowedSource : public DemSource {
 public:
  pm::Heightfield read(SampleRect window) const override { return read(window, nullptr); }
  pm::Heightfield read_counting_voids(SampleRect window, std::size_t& file_voids) const override {
    return read(window, &file_voids);
  }
  std::uint32_t samples_crc() const override;
  bool in_memory() const override { return false; }
  std::size_t filled_void_cells() const override { return fill_ ? VoidFillOptions{}.max_region_cells : 0; }
  VoidFillWork void_fill_work() const override {
    std::lock_guard lock(work_mutex_);
    return work_;
  }

 protected:
  WindowedSource(std::string path, const DemOptions& options)
      : path_(std::move(path)),
        fill_(options.fill_voids),
        filled_(options.filled_void_cache_bytes),
        on_large_void_(options.on_large_void) {}
  /// The samples of `window` with voids filled (holes NaN) into z, which holds the returned
  /// window: `window` grown while a void region meeting it was cut by its edge. `voids`, when
  /// given: the window's void samples in the file.
  SampleRect load(SampleRect window, std::vector<double>& z, std::size_t* voids = nullptr) const;
  /// The raw samples of `window` (metres, voids NaN) into z.
  virtual void raw(SampleRect window, std::vector<double>& z) const = 0;
  /// grid_ from the header; `measure`: also the scale error (not needed under a warp).
  void set_grid(int width, int height, const detail::Georef& geo, const DemOptions& options,
                const std::string& height_note, bool measure);

  std::string path_;

 private:
  pm::Heightfield read(SampleRect window, std::size_t* file_voids) const;
  bool fill_;
  mutable CappedVoids capped_;
  mutable FilledVoids filled_;
  /// Void regions whose box has more cells than this are solved one read at a time (load()).
  static constexpr std::size_t kUnsharedSolveCells = 64 * 64;
  mutable std::mutex large_fill_mutex_;
  mutable std::mutex work_mutex_;
  mutable VoidFillWork work_;
  std::function<void(const VoidSolveNotice&)> on_large_void_;  // DemOptions::on_large_void
};

void WindowedSource::set_grid(int width, int height, const detail::Georef& geo, const DemOptions& options,
                              const std::string& height_note, bool measure) {
  grid_.width = width;
  grid_.height = height;
  grid_.transform = detail::world_transform(path_, width, height, geo, options, grid_.frame);
  grid_.crs_wkt = geo.crs_wkt;
  if (!geo.crs_wkt.empty() && geo.kind != detail::Georef::Kind::None) {
    const auto& n = geo.native;
    grid_.crs_transform = pm::GridTransform{n[0], n[1], n[2], n[3], n[4], n[5]};
  }
  grid_.vertical_datum = geo.vertical_datum;
  grid_.source = path_;
  // The scale error at read_dem's points, found through read(); a warped frame measures its own.
  const std::optional<double> error =
      measure ? detail::scale_error_by_reads(grid_, [this](SampleRect r) { return read(r); }) : std::nullopt;
  grid_.scale_error = error;
  grid_.frame += detail::scale_error_note(error, false) + height_note;
}

/// `next` grown by `margin` samples past each edge of `held` that the extent `e` of a region
/// touches (so the region may go on there), cut by the grid.
SampleRect grown(SampleRect next, SampleRect held, SampleRect e, int margin, int width, int height) {
  if (e.col0 == held.col0) next.col0 = std::max(0, std::min(next.col0, held.col0 - margin));
  if (e.row0 == held.row0) next.row0 = std::max(0, std::min(next.row0, held.row0 - margin));
  if (e.col1 == held.col1) next.col1 = std::min(width - 1, std::max(next.col1, held.col1 + margin));
  if (e.row1 == held.row1) next.row1 = std::min(height - 1, std::max(next.row1, held.row1 + margin));
  return next;
}

bool meets(SampleRect a, SampleRect b) {
  return a.col0 <= b.col1 && b.col0 <= a.col1 && a.row0 <= b.row1 && b.row0 <= a.row1;
}

SampleRect WindowedSource::load(SampleRect window, std::vector<double>& z, std::size_t* voids) const {
  const int width = grid_.width, height = grid_.height;
  check_window(window, path_);
  SampleRect held = window;
  VoidFillOptions fill;
  fill.threads = 1;  // readers run in parallel already; the bits do not depend on it
  fill.keep_filled_from = FilledVoids::kKeepFrom;
  fill.on_solve = on_large_void_;
  const auto all_finite = [&] {
    return std::all_of(z.begin(), z.end(), [](double v) { return std::isfinite(v); });
  };
  for (int margin = 16;; margin *= 2) {
    raw(held, z);
    if (voids && held == window)
      *voids = std::size_t(std::count_if(z.begin(), z.end(), [](double v) { return !std::isfinite(v); }));
    if (!fill_ || all_finite()) break;
    // A window holding the whole grid with no valid sample: read_dem's refusal (filling would
    // have no neighbour to start from).
    if (held.col0 == 0 && held.row0 == 0 && held.col1 == width - 1 && held.row1 == height - 1 &&
        std::none_of(z.begin(), z.end(), [](double v) { return std::isfinite(v); }))
      throw DemError(path_, "has no valid sample (all " + std::to_string(z.size()) + " are void)");
    const auto count = [&](std::size_t reused, const VoidFillStats* stats) {
      std::lock_guard lock(work_mutex_);
      work_.reused += reused;
      if (stats) work_.solved += stats->filled_regions, work_.solved_samples += stats->filled;
    };
    count(filled_.apply(held, z), nullptr);
    if (all_finite()) break;
    // Small regions first, on this thread alone; larger ones (capped by `small`) one read at a
    // time, after taking what another read may have just kept: two readers meeting the same gap
    // would otherwise both solve it, with the solver's memory (about 115 bytes a void sample)
    // twice over. The bits are the same either way: regions are never 4-adjacent, so filling
    // the small ones first changes no larger region's neighbours.
    VoidFillOptions small = fill;
    small.max_region_cells = kUnsharedSolveCells;
    VoidFillStats stats = fill_voids_in_window(z, held, width, height, small);
    count(0, &stats);
    filled_.add(stats.kept);
    if (stats.capped_regions > 0) {
      std::lock_guard lock(large_fill_mutex_);
      count(filled_.apply(held, z), nullptr);
      stats = all_finite() ? VoidFillStats{} : fill_voids_in_window(z, held, width, height, fill);
      count(0, &stats);
      filled_.add(stats.kept);
    }
    SampleRect next = held;
    if (stats.capped_regions == 0 && capped_.empty()) {
      for (const OpenVoidRegion& o : stats.open)
        if (meets(o.extent, window)) next = grown(next, held, o.extent, margin, width, height);
    } else {  // the regions left void: capped (known before, or now) or cut
      for (const auto& [box, runs] : void_regions(z, held)) {
        if (!meets(box, window) || capped_.holds(runs)) continue;
        if (box.samples() > fill.max_region_cells) {
          capped_.add(runs);
        } else {
          next = grown(next, held, box, margin, width, height);
        }
      }
    }
    if (next == held) break;
    held = next;
  }
  return held;
}

pm::Heightfield WindowedSource::read(SampleRect window, std::size_t* file_voids) const {
  std::vector<double> z;
  std::size_t voids = 0;
  const SampleRect held = load(window, z, file_voids ? &voids : nullptr);
  pm::Heightfield b(window.width(), window.height());
  std::vector<std::uint8_t> mask(b.size(), 1);
  bool holes = false;
  for (int j = 0; j < window.height(); ++j)
    for (int i = 0; i < window.width(); ++i) {
      const double v = z[std::size_t(window.row0 - held.row0 + j) * std::size_t(held.width()) +
                         std::size_t(window.col0 - held.col0 + i)];
      const std::size_t k = std::size_t(j) * std::size_t(b.width()) + std::size_t(i);
      if (std::isfinite(v)) {
        b.samples()[k] = v;
      } else {
        mask[k] = 0;
        holes = true;
      }
    }
  if (holes) b.set_mask(std::move(mask));
  describe(b, window);
  if (file_voids) *file_voids = voids;
  return b;
}

std::uint32_t WindowedSource::samples_crc() const {
  // Bands through load(), not read(): its buffers are reused, as freshly mapped pages for every
  // band cost more than the reads (measured 3.5 s instead of 0.43 s for 8193 x 8193 samples).
  const int width = grid_.width, height = grid_.height;
  const int rows = std::max(1, (1 << 18) / width);
  detail::SampleCrc crc;
  std::vector<double> z, row(std::size_t(width), 0.0);
  std::vector<std::uint8_t> mask(std::size_t(width), 1);
  for (int r0 = 0; r0 < height; r0 += rows) {
    const SampleRect band{0, r0, width - 1, std::min(height, r0 + rows) - 1};
    const SampleRect held = load(band, z);
    for (int r = band.row0; r <= band.row1; ++r) {
      const double* v = z.data() + std::size_t(r - held.row0) * std::size_t(width);
      for (std::size_t i = 0; i < row.size(); ++i) {
        const bool valid = std::isfinite(v[i]);
        row[i] = valid ? v[i] : 0.0;
        mask[i] = valid ? 1 : 0;
      }
      crc.add_row(row.data(), mask.data(), row.size());
    }
  }
  return crc.value();
}

class GdalSource final : public WindowedSource {
 public:
  GdalSource(const std::string& path, const DemOptions& options, GDALDatasetUniquePtr ds,
             detail::GdalBand band, bool measure)
      : WindowedSource(path, options), band_(std::move(band)) {
    int has_nodata = 0;
    ds->GetRasterBand(band_.index)->GetNoDataValue(&has_nodata);
    empty_is_void_ = has_nodata != 0;
    pool_.push_back(std::move(ds));
    set_grid(band_.width, band_.height, band_.geo, options, measure ? band_.height_note : "", measure);
  }

  bool may_have_data(SampleRect window) const override {
    if (!empty_is_void_) return true;  // a VRT without nodata reads 0 where it has no tile
    GDALDatasetUniquePtr ds = borrow();
    const int status =
        ds->GetRasterBand(band_.index)
            ->GetDataCoverageStatus(window.col0, window.row0, window.width(), window.height(), 0, nullptr);
    give_back(std::move(ds));
    return status != GDAL_DATA_COVERAGE_STATUS_EMPTY;
  }

 protected:
  void raw(SampleRect window, std::vector<double>& z) const override {
    std::error_code ec;
    if (detail::names_a_file(path_) && !fs::is_regular_file(path_, ec))
      throw DemError(path_, "no longer exists (removed while it was being read?)");
    GDALDatasetUniquePtr ds = borrow();
    detail::read_gdal_window(path_, *ds, band_, window, z);
    give_back(std::move(ds));
  }

 private:
  detail::CacheCap cache_;
  detail::GdalBand band_;
  bool empty_is_void_ = false;  ///< the band has a nodata value, which windows without data read as
  mutable std::mutex mutex_;
  mutable std::vector<GDALDatasetUniquePtr> pool_;  ///< datasets no read is using

  /// A dataset of the pool, or a new one when every one is in use.
  GDALDatasetUniquePtr borrow() const {
    {
      std::lock_guard lock(mutex_);
      if (!pool_.empty()) {
        GDALDatasetUniquePtr ds = std::move(pool_.back());
        pool_.pop_back();
        return ds;
      }
    }
    return detail::open_gdal(path_);
  }
  void give_back(GDALDatasetUniquePtr ds) const {
    std::lock_guard lock(mutex_);
    pool_.push_back(std::move(ds));
  }
};

class HgtSource final : public WindowedSource {
 public:
  HgtSource(const std::string& path, const DemOptions& options, detail::HgtTile tile, bool measure)
      : WindowedSource(path, options), n_(tile.n) {
    set_grid(n_, n_, tile.geo, options, "", measure);
  }

 protected:
  void raw(SampleRect window, std::vector<double>& z) const override {
    detail::read_hgt_window(path_, n_, window, z);
  }

 private:
  int n_;
};

/// An unnamed file in the temporary folder (TMPDIR, else /tmp), removed by the system when it is
/// closed, even if the process is killed. Errors name `owner` (the input it holds data of).
class TempFile {
 public:
  explicit TempFile(const std::string& owner) : owner_(owner) {
    const char* tmpdir = std::getenv("TMPDIR");
    dir_ = tmpdir != nullptr && *tmpdir != '\0' ? tmpdir : "/tmp";
    fd_ = ::open(dir_.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
    if (fd_ < 0 && (errno == EOPNOTSUPP || errno == EISDIR || errno == EINVAL)) {
      // A file system without unnamed files: a named one, unlinked at once.
      std::string name = (fs::path(dir_) / "terralod-XXXXXX").string();
      fd_ = ::mkostemp(name.data(), O_CLOEXEC);
      if (fd_ >= 0) ::unlink(name.c_str());
    }
    if (fd_ < 0) fail("cannot create", errno);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() { ::close(fd_); }

  void append(const void* data, std::size_t bytes) {
    const char* p = static_cast<const char*>(data);
    while (bytes > 0) {
      const ssize_t n = ::write(fd_, p, bytes);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail("cannot write to", n < 0 ? errno : ENOSPC);  // 0 bytes: the disk is full
      p += n, bytes -= std::size_t(n), size_ += std::uint64_t(n);
    }
  }
  void read_at(void* data, std::size_t bytes, std::uint64_t offset) const {
    char* p = static_cast<char*>(data);
    while (bytes > 0) {
      const ssize_t n = ::pread(fd_, p, bytes, off_t(offset));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail("cannot read back", n < 0 ? errno : EIO);  // 0 bytes: it ended early
      p += n, bytes -= std::size_t(n), offset += std::uint64_t(n);
    }
  }

 private:
  // `e`: the errno of the failed call (taken at once: a later call may change errno).
  [[noreturn]] void fail(const std::string& what, int e) const {
    throw DemError(owner_, what + " its decoded samples in a temporary file in " + dir_ + " (" +
                               std::to_string(size_ >> 20) + " MiB written): " + std::strerror(e) +
                               "; TMPDIR names the folder used");
  }
  std::string owner_, dir_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

/// A DEM that can only be read from its first row on (heightmap images: PNG cannot be read from
/// the middle; ASCII grids: a text), decoded once, at opening, into a TempFile, from which windows
/// are read: memory of one band of rows, disk of 4 bytes a sample where every value is a float
/// exactly (8- and 16-bit images), else 8. Reading such a file window by window would decode it
/// from its first row again at every read behind the last one. `Rows` is detail::HeightmapRows
/// (raw values, turned into metres at each read by `scale` and `offset` as read_heightmap turns
/// them) or detail::AsciiGridRows (metres: scale 1, offset 0).
class DecodedSource final : public WindowedSource {
 public:
  template <typename Rows>
  DecodedSource(const std::string& path, const DemOptions& options, Rows& rows, bool floats, double scale,
                double offset, const detail::Georef& geo, const std::string& height_note, bool measure)
      : WindowedSource(path, options),
        file_(path),
        width_(rows.width()),
        doubles_(!floats),
        scale_(scale),
        offset_(offset) {
    std::vector<double> band;
    std::vector<float> narrow;
    while (rows.next(band) > 0) {
      if (doubles_) {
        file_.append(band.data(), band.size() * sizeof(double));
      } else {
        narrow.assign(band.begin(), band.end());
        file_.append(narrow.data(), narrow.size() * sizeof(float));
      }
    }
    set_grid(width_, rows.height(), geo, options, measure ? height_note : "", measure);
  }

 protected:
  void raw(SampleRect window, std::vector<double>& z) const override {
    const std::size_t w = std::size_t(window.width()), size = doubles_ ? sizeof(double) : sizeof(float);
    z.resize(window.samples());
    std::vector<unsigned char> row(w * size);
    for (int r = window.row0; r <= window.row1; ++r) {
      const std::uint64_t at = (std::uint64_t(r) * std::uint64_t(width_) + std::uint64_t(window.col0)) * size;
      file_.read_at(row.data(), row.size(), at);
      double* out = z.data() + std::size_t(r - window.row0) * w;
      for (std::size_t i = 0; i < w; ++i) {
        double v;
        if (doubles_) {
          std::memcpy(&v, row.data() + i * sizeof(double), sizeof(double));
        } else {
          float f;
          std::memcpy(&f, row.data() + i * sizeof(float), sizeof(float));
          v = f;
        }
        out[i] = detail::heightmap_metres(v, scale_, offset_);
      }
    }
  }

 private:
  TempFile file_;
  int width_ = 0;
  bool doubles_ = false;
  double scale_ = 1.0, offset_ = 0.0;  ///< heightmap_metres' (1 and 0 for ASCII grids)
};

}  // namespace

std::unique_ptr<DemSource> open_dem_source(const std::string& path, const DemOptions& options) {
  detail::check_options(options);
  try {
    GDALDatasetUniquePtr ds;
    const Format format = detail::dem_format(path, options, ds);
    // A frame that warps reads the native grid through a warped source (dem_frame.hpp), window
    // by window as well; the native source then skips measuring a scale error nobody reports.
    if (format == Format::Hgt) {
      detail::HgtTile tile = detail::hgt_tile(path);
      const bool warps = detail::frame_warps(tile.geo.crs_wkt, true, options.crs);
      auto native = std::make_unique<HgtSource>(path, options, std::move(tile), !warps);
      if (!warps) return native;
      return detail::warped_source(path, std::move(native), options.crs, "");
    }
    if (format == Format::Gdal) {
      detail::GdalBand band = detail::gdal_band(path, *ds, false, options.band);
      const bool has_crs_transform = !band.geo.crs_wkt.empty() && band.geo.kind != detail::Georef::Kind::None;
      const bool warps = detail::frame_warps(band.geo.crs_wkt, has_crs_transform, options.crs);
      const std::string height_note = band.height_note;
      auto native = std::make_unique<GdalSource>(path, options, std::move(ds), std::move(band), !warps);
      if (!warps) return native;
      return detail::warped_source(path, std::move(native), options.crs, height_note);
    }
    if (format == Format::Heightmap) {
      const bool warps = detail::frame_warps("", false, options.crs);
      detail::HeightmapRows rows(path, false);
      const std::string note = detail::heightmap_note(options);
      auto native =
          std::make_unique<DecodedSource>(path, options, rows, rows.exact_in_float(), options.vertical_scale,
                                          options.vertical_offset, detail::Georef{}, note, !warps);
      if (!warps) return native;
      return detail::warped_source(path, std::move(native), options.crs, note);
    }
    // An Esri ASCII grid (Format::AsciiGrid).
    detail::AsciiGridRows rows(path, false);
    const detail::Georef geo = rows.georef();
    const bool warps = detail::frame_warps(
        geo.crs_wkt, !geo.crs_wkt.empty() && geo.kind != detail::Georef::Kind::None, options.crs);
    auto native = std::make_unique<DecodedSource>(path, options, rows, false, 1.0, 0.0, geo, "", !warps);
    if (!warps) return native;
    return detail::warped_source(path, std::move(native), options.crs, "");
  } catch (const fs::filesystem_error& e) {
    throw DemError(path, e.what());
  }
}

}  // namespace terralod::blocks
