// Tests for WGS 84 geodesy (pm/geodesy.hpp) and quantized-mesh-1.0 tiles
// (blocks/quantized_mesh.hpp), read back with the independent reader of tests/support.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <set>

#include "quantized_mesh_reader.hpp"
#include "terralod/blocks/quantized_mesh.hpp"
#include "terralod/pm/geodesy.hpp"

namespace {

namespace tb = terralod::blocks;
namespace pm = terralod::pm;
namespace tt = terralod::test;

TEST(Geodesy, EcefRoundTripAndKnownPoints) {
  const pm::Ecef eq = pm::ecef_from_geodetic({0, 0, 0});
  EXPECT_DOUBLE_EQ(eq[0], pm::kWgs84A);
  EXPECT_NEAR(eq[1], 0, 1e-9);
  const pm::Ecef pole = pm::ecef_from_geodetic({0, 90, 0});
  EXPECT_NEAR(pole[2], pm::kWgs84B, 1e-6);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-89.9, 89.9), h(-500, 9000);
  for (int i = 0; i < 1000; ++i) {
    const pm::Geodetic g{lon(rng), lat(rng), h(rng)};
    const pm::Geodetic b = pm::geodetic_from_ecef(pm::ecef_from_geodetic(g));
    EXPECT_NEAR(b.lon_deg, g.lon_deg, 1e-11);
    EXPECT_NEAR(b.lat_deg, g.lat_deg, 1e-11);
    EXPECT_NEAR(b.height, g.height, 1e-6);
  }
}

// Cesium's isScaledSpacePointVisible: is the scaled point p visible from the scaled camera c
// past the unit sphere's horizon?
bool visible_scaled(const pm::Ecef& p, const pm::Ecef& c) {
  const double vh2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2] - 1.0;
  const pm::Ecef vt{p[0] - c[0], p[1] - c[1], p[2] - c[2]};
  const double vt_dot_vc = -(vt[0] * c[0] + vt[1] * c[1] + vt[2] * c[2]);
  const double vt2 = vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2];
  const bool occluded = vh2 < 0 ? vt_dot_vc > 0 : (vt_dot_vc > vh2 && vt_dot_vc * vt_dot_vc / vt2 > vh2);
  return !occluded;
}

// The horizon occlusion point's promise: from every camera that cannot see it, no point of the
// tile can be seen either.
TEST(Geodesy, HorizonPointHidesTheTileWheneverItIsHidden) {
  std::vector<pm::Ecef> pts;
  for (int i = 0; i <= 10; ++i)
    for (int j = 0; j <= 10; ++j)
      pts.push_back(
          pm::ecef_from_geodetic({-72 + 0.1 * i, 44 + 0.1 * j, 200.0 + 150.0 * ((i * 7 + j * 3) % 11)}));
  const pm::EcefSphere s = pm::bounding_sphere(pts);
  for (const pm::Ecef& p : pts)
    EXPECT_LE(std::hypot(p[0] - s.center[0], p[1] - s.center[1], p[2] - s.center[2]), s.radius * (1 + 1e-12));
  const pm::Ecef h = pm::horizon_occlusion_point(pts, s.center);
  ASSERT_FALSE(std::isnan(h[0]));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> lon(-180, 180), lat(-89, 89), alt(100, 2e7);
  std::size_t hidden = 0;
  for (int k = 0; k < 20000; ++k) {
    const pm::Ecef cam = pm::ecef_from_geodetic({lon(rng), lat(rng), alt(rng)});
    const pm::Ecef c{cam[0] / pm::kWgs84A, cam[1] / pm::kWgs84A, cam[2] / pm::kWgs84B};
    if (visible_scaled(h, c)) continue;
    ++hidden;
    for (const pm::Ecef& p : pts) {
      const pm::Ecef q{p[0] / pm::kWgs84A, p[1] / pm::kWgs84A, p[2] / pm::kWgs84B};
      ASSERT_FALSE(visible_scaled(q, c))
          << "camera " << k << " sees a point while the horizon point is hidden";
    }
  }
  EXPECT_GT(hidden, 1000u);
}

TEST(QuantizedMesh, TilingMatchesCesiumsGeographicScheme) {
  EXPECT_EQ(tb::tile_rect({0, 0, 0}), (tb::GeoRect{-180, -90, 0, 90}));
  EXPECT_EQ(tb::tile_rect({0, 1, 0}), (tb::GeoRect{0, -90, 180, 90}));
  EXPECT_EQ(tb::tile_rect({1, 3, 1}), (tb::GeoRect{90, 0, 180, 90}));
  EXPECT_NEAR(tb::level_max_geometric_error(0), 77067.34, 0.01);
  EXPECT_DOUBLE_EQ(tb::level_max_geometric_error(10), tb::level_max_geometric_error(0) / 1024);
}

TEST(QuantizedMesh, OctEncodingDecodesWithinABytesPrecision) {
  std::mt19937 rng(5);
  std::normal_distribution<double> nd;
  double worst = 0;
  for (int i = 0; i < 5000; ++i) {
    pm::Ecef v{nd(rng), nd(rng), nd(rng)};
    const double l = std::hypot(v[0], v[1], v[2]);
    for (double& x : v) x /= l;
    const auto e = tb::oct_encode(v);
    const auto d = tt::oct_decode(e[0], e[1]);
    worst = std::max(worst, std::acos(std::min(1.0, v[0] * d[0] + v[1] * d[1] + v[2] * d[2])));
  }
  std::printf("oct encoding: worst angle %.3f degrees\n", worst * 180 / 3.141592653589793);
  EXPECT_LT(worst * 180 / 3.141592653589793, 1.0);
}

// A grid of vertices over a tile, shuffled so that the encoder must reorder them.
struct GridTile {
  tb::GeoRect rect;
  int n = 0;  // cells per side
  std::vector<pm::Geodetic> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  /// The grid position (i, j) nearest to (lon, lat).
  std::array<long, 2> key(double lon, double lat) const {
    return {std::lround((lon - rect.west) / (rect.east - rect.west) * n),
            std::lround((lat - rect.south) / (rect.north - rect.south) * n)};
  }
};
GridTile grid_tile(tb::TileId id, int n) {
  GridTile g;
  g.rect = tb::tile_rect(id);
  g.n = n;
  std::vector<std::uint32_t> slot((n + 1) * (n + 1));
  for (std::uint32_t i = 0; i < slot.size(); ++i) slot[i] = i;
  std::shuffle(slot.begin(), slot.end(), std::mt19937(11));
  g.vertices.resize(slot.size());
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const double lon = g.rect.west + (g.rect.east - g.rect.west) * i / n;
      const double lat = g.rect.south + (g.rect.north - g.rect.south) * j / n;
      g.vertices[slot[std::size_t(j * (n + 1) + i)]] = {
          lon, lat, 300.0 + 400.0 * std::sin(i * 0.3) * std::cos(j * 0.2)};
    }
  auto at = [&](int i, int j) { return slot[std::size_t(j * (n + 1) + i)]; };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      g.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      g.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  return g;
}

void expect_round_trip(const GridTile& g, const tb::QuantizedMeshTile& t, const tt::DecodedTile& d) {
  ASSERT_EQ(d.u.size(), g.vertices.size());
  EXPECT_EQ(d.u, std::vector<int>(t.u.begin(), t.u.end()));
  EXPECT_EQ(d.v, std::vector<int>(t.v.begin(), t.v.end()));
  EXPECT_EQ(d.h, std::vector<int>(t.h.begin(), t.h.end()));
  EXPECT_EQ(d.triangles, t.triangles);
  EXPECT_EQ(d.edges, t.edges);
  EXPECT_EQ(d.min_height, t.min_height);
  EXPECT_EQ(d.max_height, t.max_height);
  // Decoded positions are the input's within half a quantum.
  const double du = (g.rect.east - g.rect.west) / 32767, dv = (g.rect.north - g.rect.south) / 32767;
  const double dh = (d.max_height - d.min_height) / 32767;
  std::map<std::array<long, 2>, std::size_t> input_at;
  for (std::size_t v = 0; v < g.vertices.size(); ++v)
    input_at[g.key(g.vertices[v].lon_deg, g.vertices[v].lat_deg)] = v;
  std::vector<std::size_t> input_of(d.u.size());
  for (std::size_t i = 0; i < d.u.size(); ++i) {
    const double lon = g.rect.west + d.u[i] * du, lat = g.rect.south + d.v[i] * dv;
    const auto it = input_at.find(g.key(lon, lat));
    ASSERT_NE(it, input_at.end()) << "vertex " << i << " is not an input vertex";
    input_of[i] = it->second;
    const pm::Geodetic& in = g.vertices[it->second];
    EXPECT_LE(std::abs(lon - in.lon_deg), du / 2 * (1 + 1e-9));
    EXPECT_LE(std::abs(lat - in.lat_deg), dv / 2 * (1 + 1e-9));
    EXPECT_LE(std::abs(d.min_height + d.h[i] * dh - in.height), dh / 2 + 1e-3);
  }
  // The triangles are the input's.
  std::set<std::array<std::size_t, 3>> want, got;
  auto canonical = [](std::array<std::size_t, 3> t) {
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    return t;
  };
  for (const auto& t3 : g.triangles) want.insert(canonical({t3[0], t3[1], t3[2]}));
  for (const auto& t3 : d.triangles)
    got.insert(canonical({input_of[t3[0]], input_of[t3[1]], input_of[t3[2]]}));
  EXPECT_EQ(want, got);
  // Normals: the area-weighted normals of the input surface, within the oct encoding's
  // precision (the encoder works on the quantized positions).
  if (!d.normals.empty()) {
    ASSERT_EQ(d.normals.size(), d.u.size());
    std::vector<pm::Ecef> p, sum(g.vertices.size(), pm::Ecef{0, 0, 0});
    for (const pm::Geodetic& v : g.vertices) p.push_back(pm::ecef_from_geodetic(v));
    for (const auto& tri : g.triangles) {
      const pm::Ecef &a = p[tri[0]], &b = p[tri[1]], &c = p[tri[2]];
      const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
                   e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      const double f[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                           e1[0] * e2[1] - e1[1] * e2[0]};
      for (std::uint32_t v : tri)
        for (int k = 0; k < 3; ++k) sum[v][std::size_t(k)] += f[k];
    }
    for (std::size_t i = 0; i < d.u.size(); ++i) {
      const auto n = tt::oct_decode(d.normals[i][0], d.normals[i][1]);
      const pm::Ecef& s = sum[input_of[i]];
      const double cosine = (n[0] * s[0] + n[1] * s[1] + n[2] * s[2]) / std::hypot(s[0], s[1], s[2]);
      EXPECT_GT(cosine, std::cos(1.5 * 3.141592653589793 / 180)) << "normal of vertex " << i;
    }
  }
  // Edge lists: exactly the vertices on each edge.
  for (std::size_t i = 0; i < d.u.size(); ++i) {
    const bool on[4] = {d.u[i] == 0, d.v[i] == 0, d.u[i] == 32767, d.v[i] == 32767};
    for (int e = 0; e < 4; ++e)
      EXPECT_EQ(on[e], std::count(d.edges[std::size_t(e)].begin(), d.edges[std::size_t(e)].end(), i) == 1);
  }
  // CCW in (u, v).
  for (const auto& tri : d.triangles) {
    const long ax = d.u[tri[0]], ay = d.v[tri[0]], bx = d.u[tri[1]], by = d.v[tri[1]], cx = d.u[tri[2]],
               cy = d.v[tri[2]];
    EXPECT_GT((bx - ax) * (cy - ay) - (by - ay) * (cx - ax), 0);
  }
}

TEST(QuantizedMesh, TileRoundTripsThroughTheIndependentReader) {
  const GridTile g = grid_tile({12, 2425, 2958}, 16);
  const tb::QuantizedMeshTile t =
      tb::make_quantized_mesh(g.rect, g.vertices, g.triangles, {.normals = true, .metadata = "{\"a\": 1}"});
  const std::vector<std::uint8_t> raw = tb::encode_quantized_mesh(t);
  const std::vector<std::uint8_t> gz = tb::gzip(raw);
  std::printf("17 x 17 tile: %zu bytes, %zu gzipped (%.2f bytes per vertex)\n", raw.size(), gz.size(),
              double(gz.size()) / double(g.vertices.size()));
  const tt::DecodedTile d = tt::decode_quantized_mesh_tile(gz);
  EXPECT_FALSE(d.wide_indices);
  expect_round_trip(g, t, d);
  EXPECT_EQ(d.metadata, "{\"a\": 1}");
  ASSERT_EQ(d.normals.size(), d.u.size());
  for (int k = 0; k < 3; ++k) EXPECT_EQ(d.center[k], t.center[std::size_t(k)]);
  EXPECT_EQ(d.sphere[3], t.sphere.radius);
  // Without extensions the tile ends after the north edge.
  tb::QuantizedMeshTile bare = t;
  bare.normals.clear();
  bare.metadata.clear();
  const tt::DecodedTile db = tt::decode_quantized_mesh_tile(tb::encode_quantized_mesh(bare));
  EXPECT_TRUE(db.normals.empty() && db.metadata.empty());
}

TEST(QuantizedMesh, MoreThan65536VerticesUseWideIndices) {
  const GridTile g = grid_tile({15, 19000, 24000}, 260);  // 261^2 = 68,121 vertices
  const tb::QuantizedMeshTile t =
      tb::make_quantized_mesh(g.rect, g.vertices, g.triangles, {.normals = false, .metadata = {}});
  const tt::DecodedTile d = tt::decode_quantized_mesh_tile(tb::encode_quantized_mesh(t));
  EXPECT_TRUE(d.wide_indices);
  expect_round_trip(g, t, d);
}

TEST(QuantizedMesh, LayerJsonListsTheAvailableRanges) {
  const std::string j = tb::layer_json(
      "N44W072", {-72, 44, -71, 45}, {{{0, 0, 0, 0}}, {{1, 1, 1, 1}}, {{2, 2, 3, 2}}}, {"octvertexnormals"});
  for (const char* want :
       {"\"tilejson\": \"2.1.0\"", "\"format\": \"quantized-mesh-1.0\"", "\"scheme\": \"tms\"",
        "\"projection\": \"EPSG:4326\"", "\"maxzoom\": 2", "\"extensions\": [\"octvertexnormals\"]",
        "{\"startX\": 2, \"startY\": 2, \"endX\": 3, \"endY\": 2}", "\"bounds\": [-72, 44, -71, 45]"})
    EXPECT_NE(j.find(want), std::string::npos) << want << "\n" << j;
}

TEST(QuantizedMesh, ReaderRefusesTruncatedTiles) {
  const GridTile g = grid_tile({10, 600, 700}, 4);
  const std::vector<std::uint8_t> raw =
      tb::encode_quantized_mesh(tb::make_quantized_mesh(g.rect, g.vertices, g.triangles));
  for (std::size_t n : {std::size_t(10), std::size_t(88), std::size_t(100), raw.size() / 2})
    EXPECT_THROW(tt::decode_quantized_mesh_tile(std::span(raw).first(n)), std::runtime_error) << n;
}

}  // namespace
