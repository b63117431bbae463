// Private to the exporters: the L-infinity mesh of one tile of a geographic tiling, whose edge
// vertices are a function of the edge alone, so that neighbouring tiles of one level share them.
//
// The terrain is a field over longitude/latitude (GeoField): the GeoGrid's samples, padded with
// a ring continuing the grid's edge and a ring of `background` lattice points (so the terrain
// ends in a cliff down to the background, not in a slope across the tile), bilinear between
// lattice points, `background` beyond; holes read as background where the field is interpolated
// and are never measured.
//
// A tile's mesh (mesh_tile) lives in the quantized (u, v) coordinates of quantized-mesh:
// integers 0..32767 from west to east and south to north. It is built in three steps:
//   1. Edges. For each edge, the field's profile along it is taken at every crossing with a
//      lattice line, at `sag_divisions` equal steps (forced, see below) and at both ends, and
//      simplified by Douglas-Peucker to max_error; the kept points, at their quantized positions,
//      are the edge's vertices, and one whose rounding alone errs by more than 1/16 of the
//      tolerance at its own sample (beside a cliff) gets a twin of its height on the quantum at
//      the other side of its true position. The profile is computed from the edge's own
//      coordinates only, so the two tiles that share an edge get the same vertices, heights
//      included.
//   2. Forced points. sag_divisions rows of vertices (with the edges' forced points), each of
//      sag_divisions x cos(latitude) columns (the latitude nearest the equator among the rows
//      beside it; on a south or north edge, the edge's), so that the flat triangles a client draws
//      in Earth-centred coordinates stay close to the curved surface on large tiles: forced points
//      as far apart on the ground along the parallels as along the meridians. None lies at the
//      terrain's edge (GeoField::at_terrain_edge).
//   3. Greedy insertion (Garland & Heckbert's algorithm III, as build_greedy_tin) of the lattice
//      points inside the tile, at their rounded positions and with their own heights, into a
//      Delaunay triangulation (exact integer predicates), until every measured point is within
//      max_error of the mesh at its true position. Measured points: the tile's valid samples, the
//      background ring, a 65 x 65 grid of background points away from the terrain, and where the
//      lattice's columns lie more than two rows apart in the tile's quanta (far from the equator),
//      points between them on each row (the field there), at most two rows apart. On a
//      lattice 16 or more quanta between samples, a point whose rounded position is a vertex
//      already goes to another corner of its quantum cell (at the top of a cliff the rounding
//      alone tilts the steep triangles by metres); on a coarser one, only a point above
//      edge_error does. Points whose rounded position lies on the tile's boundary, or that find
//      no free corner, are measured but not inserted (their error is then whatever the mesh
//      gives them), and the next worst point of their triangle is inserted instead.
// tile_error then measures a mesh exactly as a client decodes it (quantized heights included).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "terralod/blocks/geo_grid.hpp"
#include "terralod/blocks/quantized_mesh.hpp"

namespace terralod::blocks::detail {

/// lon in [-180, 180): one meridian, one value, exactly (180 and -180, or a longitude past 180).
inline double one_meridian(double lon) {
  const double m = std::remainder(lon, 360.0);
  return m == 180.0 ? -180.0 : m;
}

class GeoField {
 public:
  GeoField(const GeoGrid& grid, double background);
  const GeoGrid& grid() const { return g_; }
  double background() const { return background_; }

  /// Lattice rings around the grid: the first continues the grid's edge (the nearest sample's
  /// height), the second is the background, so the terrain ends in a one-step apron and then a
  /// cliff. Samples are then never at the top of the cliff, where a vertex's rounding to the
  /// tile's lattice would tilt the steep triangles around it.
  static constexpr int kPad = 2;

  /// The lattice point (c, r), c in [-kPad, width - 1 + kPad], r likewise: a valid sample's height;
  /// the nearest sample's on the first ring; the background on the second; NaN for a hole (not
  /// measured). A grid that goes around the Earth (GeoGrid::period) has no ring east or west: its
  /// columns continue across the antimeridian, any number of turns.
  double lattice(int c, int r) const {
    if (period_ > 0 && (c < 0 || c >= g_.width)) c = (c % period_ + period_) % period_;
    const bool in = c >= 0 && r >= 0 && c < g_.width && r < g_.height;
    if (in) return g_.valid(c, r) ? g_.z(c, r) : std::numeric_limits<double>::quiet_NaN();
    if (c < -1 || r < -1 || c > g_.width || r > g_.height) return background_;
    const int cc = std::clamp(c, 0, g_.width - 1), rr = std::clamp(r, 0, g_.height - 1);
    return g_.valid(cc, rr) ? g_.z(cc, rr) : background_;
  }
  /// Bilinear between lattice points (holes as background), background outside the rings. On a
  /// grid around the Earth, lon is first taken as one_meridian(lon), so that the two sides of the
  /// antimeridian (+-180, or a tile placed 360 degrees away) read the same columns, bit for bit;
  /// and where such a grid's first or last row lies within a row of a pole but not on it (cell
  /// centres), the field between that row and the pole runs linearly to the row's mean, which is
  /// its value at the pole, exactly: every longitude there is one point.
  double at(double lon, double lat) const;
  /// Whether at(lon, lat) lies in a lattice cell that is not all terrain (valid samples, the
  /// first ring beside them) but has terrain within two cells of it, the wider side's both ways:
  /// at the terrain's edge, where the field falls from the terrain to the background. A vertex
  /// placed there, off the lattice, at a height between the two or the background's, is joined to
  /// terrain vertices by triangles that pass between the measured points and pull the terrain
  /// down (a tile's forced points are therefore never placed there).
  bool at_terrain_edge(double lon, double lat) const;
  /// The same on lattice row r (linear between the two columns around lon) and on column c.
  double on_row(double lon, int r) const;
  double on_col(int c, double lat) const;

 private:
  /// Whether lattice point (c, r) is terrain: a valid sample, or the first ring beside one.
  bool terrain(int c, int r) const {
    if (period_ > 0 && (c < 0 || c >= g_.width)) c = (c % period_ + period_) % period_;
    if (c < -1 || r < -1 || c > g_.width || r > g_.height) return false;
    return g_.valid(std::clamp(c, 0, g_.width - 1), std::clamp(r, 0, g_.height - 1));
  }
  double value(int c, int r) const {
    const double v = lattice(c, r);
    return v == v ? v : background_;
  }
  /// The value between edge row `r` (its value v there) and the pole `pole` beyond it, at lat.
  double toward_pole(double v, int r, double pole, double lat) const {
    const double t = (lat - g_.lat(r)) / ((lat > 0 ? 90.0 : -90.0) - g_.lat(r));
    return t >= 1.0 ? pole : v + t * (pole - v);
  }
  const GeoGrid& g_;
  double background_;
  int period_;  ///< GeoGrid::period()
  /// Around the Earth with a row within a row of the pole: that row's mean (see at()); else NaN.
  double pole_north_, pole_south_;
};

struct TileMesh {
  std::vector<std::array<int, 2>> uv;                   ///< quantized positions 0..32767
  std::vector<double> heights;                          ///< metres, before height quantization
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< CCW in (u, v)
  double error = 0;       ///< the greedy's error at the unquantized heights (tile_error is exact)
  std::size_t stuck = 0;  ///< triangles left above max_error with no insertable point
};

struct TileMeshOptions {
  double max_error = 0;  ///< metres, inside the tile
  /// metres, for the Douglas-Peucker of the edges: a function of the level only, so that the two
  /// tiles of an edge choose the same vertices even when one of them is remeshed tighter.
  double edge_error = 0;
  int sag_divisions = 1;  ///< forced rows of the tile, columns on the equator (1 = corners only)
};

TileMesh mesh_tile(const GeoField& field, const GeoRect& rect, const TileMeshOptions& options);

/// The largest |mesh - point| over the tile's measured points (see above) at their true
/// positions, the mesh's heights being `decoded` (what a client reads); with samples_only, over
/// the valid samples of the GeoGrid in the closed tile only. Metres.
double tile_error(const GeoField& field, const GeoRect& rect, const std::vector<std::array<int, 2>>& uv,
                  const std::vector<double>& decoded,
                  const std::vector<std::array<std::uint32_t, 3>>& triangles, bool samples_only);

}  // namespace terralod::blocks::detail
