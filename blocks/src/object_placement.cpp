// Map objects on the terrain as drawn (object_placement.hpp): anchors derived once from the
// features, a uniform grid over them culled by quadrants against the frustum, the drawn height
// under each object in view, and picking by ray (objects as screen-sized spheres, then the drawn
// mesh by an exact ray-triangle test). Memory: see the header.
#include "terralod/blocks/object_placement.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>

namespace terralod::blocks {

namespace {

// The anchor of a feature (see the contract).
WorldPoint anchor_of(const ObjectFeature& f) {
  const std::vector<WorldPoint>& ring = f.rings.at(0);
  if (f.geometry == GeometryType::Point) return ring.at(0);
  if (f.geometry == GeometryType::Line) {
    double total = 0;
    for (std::size_t k = 1; k < ring.size(); ++k)
      total += std::hypot(ring[k].x - ring[k - 1].x, ring[k].y - ring[k - 1].y);
    double left = 0.5 * total;
    for (std::size_t k = 1; k < ring.size(); ++k) {
      const double len = std::hypot(ring[k].x - ring[k - 1].x, ring[k].y - ring[k - 1].y);
      if (len > 0 && left <= len) {
        const double s = left / len;
        return {ring[k - 1].x + s * (ring[k].x - ring[k - 1].x),
                ring[k - 1].y + s * (ring[k].y - ring[k - 1].y)};
      }
      left -= len;
    }
    return ring.at(0);
  }
  // Polygon: the centroid of the exterior ring minus the holes, relative to its first vertex
  // (exact for world coordinates of any size). Holes are wound against the exterior ring or
  // not: each ring's area counts with the exterior's sign for the first ring, the opposite for
  // the others.
  const WorldPoint o = ring.at(0);
  double area = 0, cx = 0, cy = 0;
  for (std::size_t r = 0; r < f.rings.size(); ++r) {
    const std::vector<WorldPoint>& q = f.rings[r];
    double a = 0, x = 0, y = 0;
    for (std::size_t k = 0; k < q.size(); ++k) {
      const WorldPoint& p0 = q[k];
      const WorldPoint& p1 = q[(k + 1) % q.size()];
      const double x0 = p0.x - o.x, y0 = p0.y - o.y, x1 = p1.x - o.x, y1 = p1.y - o.y;
      const double c = x0 * y1 - x1 * y0;
      a += c, x += (x0 + x1) * c, y += (y0 + y1) * c;
    }
    // Signed: the exterior ring's orientation decides; holes subtract their absolute area.
    const double sign = (r == 0 || a == 0) ? 1.0 : ((a > 0) == (area > 0) ? -1.0 : 1.0);
    area += sign * a, cx += sign * x, cy += sign * y;
  }
  if (area == 0 || !std::isfinite(area)) {
    double x = 0, y = 0;
    for (const WorldPoint& p : ring) x += p.x - o.x, y += p.y - o.y;
    return {o.x + x / double(ring.size()), o.y + y / double(ring.size())};
  }
  return {o.x + cx / (3.0 * area), o.y + cy / (3.0 * area)};
}

std::string label_of(const ObjectFeature& f, const ObjectLayerInfo& layer) {
  const ObjectAttribute* a = f.attribute(layer.label_field.empty() ? std::string("name") : layer.label_field);
  return a ? a->value : std::string();
}

}  // namespace

ObjectPlacer::ObjectPlacer(const BlockDatabase& db, const std::vector<std::string>& layer_names,
                           const PlacementOptions& options)
    : opt_(options) {
  if (!(opt_.pick_radius_px > 0)) throw std::invalid_argument("pick_radius_px must be > 0");
  const std::vector<ObjectLayerInfo> all = object_layers(db);
  std::set<std::string> seen;
  for (const std::string& name : layer_names) {
    if (!seen.insert(name).second) throw std::invalid_argument("object layer '" + name + "' given twice");
    // object_features names the database when the layer is missing.
    std::vector<ObjectFeature> features = object_features(db, name);
    const auto info =
        std::find_if(all.begin(), all.end(), [&](const ObjectLayerInfo& l) { return l.name == name; });
    assert(info != all.end());
    layers_.push_back(*info);
    rules_.push_back(
        info->rules_json
            ? parse_object_rules(*info->rules_json, db.path() + ": object layer '" + name + "' rules")
            : ObjectRules::everything_as(*parse_representation(kind_name(info->kind))));
    const ObjectRules& rules = rules_.back();
    max_extent_.push_back(0.0);
    for (ObjectFeature& f : features) {
      MapObject m;
      m.layer = layers_.size() - 1;
      m.kind = info->kind;
      m.name = label_of(f, *info);
      m.named = !m.name.empty();
      if (!m.named) m.name = std::to_string(f.id);
      m.anchor = anchor_of(f);
      m.extent_m = f.geometry == GeometryType::Point ? rules.icon_size_m()
                                                     : std::max({f.max.x - f.min.x, f.max.y - f.min.y, 1e-3});
      if (!rules.priority_field().empty())
        if (const ObjectAttribute* a = f.attribute(rules.priority_field()))
          m.priority = priority_value(a->value);
      max_extent_.back() = std::max(max_extent_.back(), m.extent_m);
      m.feature = std::move(f);
      objects_.push_back(std::move(m));
    }
  }
  visible_.assign(layers_.size(), true);
  reach_.assign(layers_.size(), 0.0);
  if (objects_.size() >= std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument(db.path() + ": too many objects to place (at most 2^32 - 2)");

  // The grid: about 8 objects per cell, at most 1024 x 1024 cells, over the anchors' box.
  double x1 = 0, y1 = 0;
  if (!objects_.empty()) {
    x0_ = x1 = objects_[0].anchor.x, y0_ = y1 = objects_[0].anchor.y;
    for (const MapObject& m : objects_) {
      x0_ = std::min(x0_, m.anchor.x), x1 = std::max(x1, m.anchor.x);
      y0_ = std::min(y0_, m.anchor.y), y1 = std::max(y1, m.anchor.y);
    }
  }
  nx_ = ny_ = std::clamp(int(std::ceil(std::sqrt(double(objects_.size()) / 8.0))), 1, 1024);
  cell_w_ = std::max(x1 - x0_, 1e-9) / nx_;
  cell_h_ = std::max(y1 - y0_, 1e-9) / ny_;
  const std::size_t cells = std::size_t(nx_) * std::size_t(ny_);
  start_.assign(layers_.size(), std::vector<std::uint32_t>(cells + 1, 0));
  items_.assign(layers_.size(), {});
  item_anchors_.assign(layers_.size(), {});
  std::vector<std::size_t> cell_of(objects_.size());
  for (std::size_t k = 0; k < objects_.size(); ++k) {
    const int i = std::clamp(int(std::floor((objects_[k].anchor.x - x0_) / cell_w_)), 0, nx_ - 1);
    const int j = std::clamp(int(std::floor((objects_[k].anchor.y - y0_) / cell_h_)), 0, ny_ - 1);
    cell_of[k] = std::size_t(j) * std::size_t(nx_) + std::size_t(i);
    ++start_[objects_[k].layer][cell_of[k] + 1];
  }
  for (std::size_t l = 0; l < layers_.size(); ++l) {
    for (std::size_t c = 1; c <= cells; ++c) start_[l][c] += start_[l][c - 1];
    items_[l].resize(start_[l][cells]);
    item_anchors_[l].resize(start_[l][cells]);
  }
  std::vector<std::vector<std::uint32_t>> fill = start_;
  for (std::size_t k = 0; k < objects_.size(); ++k) {  // by id within each cell: stable order
    const std::size_t l = objects_[k].layer, at = fill[l][cell_of[k]]++;
    items_[l][at] = std::uint32_t(k);
    item_anchors_[l][at] = objects_[k].anchor;
  }
}

std::size_t ObjectPlacer::memory_bytes() const {
  // A std::string's own buffer only when it outgrew the small-string buffer inside it.
  auto heap = [](const std::string& t) { return t.capacity() > 15 ? t.capacity() + 1 : 0; };
  std::size_t n = objects_.capacity() * sizeof(MapObject) + placed_.capacity() * sizeof(PlacedObject);
  for (const MapObject& m : objects_) {
    n += heap(m.name) + m.feature.rings.capacity() * sizeof(std::vector<WorldPoint>) +
         m.feature.attributes.capacity() * sizeof(ObjectAttribute);
    for (const auto& ring : m.feature.rings) n += ring.capacity() * sizeof(WorldPoint);
    for (const ObjectAttribute& a : m.feature.attributes) n += heap(a.name) + heap(a.value);
  }
  for (std::size_t l = 0; l < layers_.size(); ++l)
    n += start_[l].capacity() * 4 + items_[l].capacity() * 4 +
         item_anchors_[l].capacity() * sizeof(WorldPoint);
  return n;
}

std::size_t ObjectPlacer::layer_index(const std::string& layer) const {
  for (std::size_t l = 0; l < layers_.size(); ++l)
    if (layers_[l].name == layer) return l;
  throw std::invalid_argument("object layer '" + layer + "' was not read by this placer");
}

void ObjectPlacer::set_layer_visible(const std::string& layer, bool visible) {
  visible_[layer_index(layer)] = visible;
}

bool ObjectPlacer::layer_visible(const std::string& layer) const { return visible_[layer_index(layer)]; }

void ObjectPlacer::visit(const TerrainRuntime& rt, const pm::View& view, int i0, int j0, int i1, int j1,
                         double zlo, double zhi) {
  const pm::Box box{{x0_ + i0 * cell_w_, y0_ + j0 * cell_h_, zlo},
                    {x0_ + i1 * cell_w_, y0_ + j1 * cell_h_, zhi}};
  // The box's distance from the eye as the camera sees it (through its ground scale: at least
  // the world distance times min_distance_scale): nothing in it is nearer.
  const double distance = view.camera().ground.min_distance_scale() * pm::distance_to_box(view.eye(), box);
  if (distance > max_reach_ || view.outside(box)) {
    ++stats_.regions_culled;
    return;
  }
  if (i1 - i0 > 1 || j1 - j0 > 1) {  // quadrants (halves of a strip)
    const int im = (i0 + i1 + 1) / 2, jm = (j0 + j1 + 1) / 2;
    visit(rt, view, i0, j0, im, jm, zlo, zhi);
    if (im < i1) visit(rt, view, im, j0, i1, jm, zlo, zhi);
    if (jm < j1) visit(rt, view, i0, jm, im, j1, zlo, zhi);
    if (im < i1 && jm < j1) visit(rt, view, im, jm, i1, j1, zlo, zhi);
    return;
  }
  ++stats_.cells_visited;
  place_cell(rt, view, std::size_t(j0) * std::size_t(nx_) + std::size_t(i0), distance);
}

void ObjectPlacer::place_cell(const TerrainRuntime& rt, const pm::View& view, std::size_t cell,
                              double cell_distance) {
  const pm::Vec3& e = view.eye();
  const pm::GroundScale& g = view.camera().ground;
  const double focal = view.focal_px();
  for (std::size_t l = 0; l < layers_.size(); ++l) {
    if (!(reach_[l] >= cell_distance)) continue;  // hidden (-inf), or its rules end nearer
    const double reach2 = reach_[l] * reach_[l];
    for (std::uint32_t k = start_[l][cell]; k < start_[l][cell + 1]; ++k) {
      const WorldPoint& a = item_anchors_[l][k];  // contiguous: the object itself only when placed
      ++stats_.objects_tested;
      // The plan offset as seen (G of the world offset: ground metres on a continent-wide frame).
      const double wx = a.x - e.x, wy = a.y - e.y;
      const double px = g.xx * wx + g.xy * wy, py = g.xy * wx + g.yy * wy;
      if (px * px + py * py > reach2) {  // the plan distance alone is beyond the rules
        ++stats_.beyond_rules;
        continue;
      }
      const double z = rt.drawn_height(a.x, a.y);
      if (std::isnan(z)) continue;
      const pm::Vec3 p{a.x, a.y, z};
      if (!view.contains(p)) continue;
      const MapObject& m = objects_[items_[l][k]];
      const double d = std::sqrt(px * px + py * py + (z - e.z) * (z - e.z));
      const double size = d > 0 ? m.extent_m * focal / d : std::numeric_limits<double>::infinity();
      const Representation draw = rules_[l].choose(d, size);
      if (draw == Representation::None) {
        ++stats_.beyond_rules;
        continue;
      }
      placed_.push_back({&m, p, draw, d});
    }
  }
}

const std::vector<PlacedObject>& ObjectPlacer::place(const TerrainRuntime& rt, const pm::View& view) {
  const auto t0 = std::chrono::steady_clock::now();
  stats_ = {};
  placed_.clear();
  const pm::Box& terrain = rt.terrain_box();
  max_reach_ = -std::numeric_limits<double>::infinity();
  for (std::size_t l = 0; l < layers_.size(); ++l) {
    reach_[l] = visible_[l] ? rules_[l].max_drawn_distance(max_extent_[l], view.focal_px())
                            : -std::numeric_limits<double>::infinity();
    max_reach_ = std::max(max_reach_, reach_[l]);
  }
  if (!objects_.empty()) visit(rt, view, 0, 0, nx_, ny_, terrain.lo.z, terrain.hi.z);
  stats_.objects_placed = placed_.size();
  view_ = view;
  frame_ = rt.stats().frame;
  stats_.place_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return placed_;
}

std::optional<PickResult> ObjectPlacer::pick(const TerrainRuntime& rt, const pm::Vec3& origin,
                                             const pm::Vec3& direction) const {
  assert(view_ && frame_ == rt.stats().frame && "pick() after place() in the same frame");
  const double len = std::sqrt(pm::dot(direction, direction));
  if (!(len > 0) || !std::isfinite(len))
    throw std::invalid_argument("pick: the ray's direction must be non-zero");
  const pm::Vec3 d{direction.x / len, direction.y / len, direction.z / len};

  // The ground: the first drawn triangle the ray meets (Moller-Trumbore, relative to the
  // origin; edges included).
  const DrawnMesh& m = rt.drawn_mesh();
  double ground_t = std::numeric_limits<double>::infinity();
  for (const auto& tri : m.triangles) {
    const pm::Vec3 a = sub(m.positions[tri[0]], origin);
    const pm::Vec3 e1 = sub(m.positions[tri[1]], m.positions[tri[0]]);
    const pm::Vec3 e2 = sub(m.positions[tri[2]], m.positions[tri[0]]);
    const pm::Vec3 p = cross(d, e2);
    const double det = pm::dot(e1, p);
    if (det == 0) continue;
    const pm::Vec3 s{-a.x, -a.y, -a.z};
    const double u = pm::dot(s, p) / det;
    if (u < -1e-12 || u > 1 + 1e-12) continue;
    const pm::Vec3 q = cross(s, e1);
    const double v = pm::dot(d, q) / det;
    if (v < -1e-12 || u + v > 1 + 1e-12) continue;
    const double t = pm::dot(e2, q) / det;
    if (t >= 0 && t < ground_t) ground_t = t;
  }

  // The objects: spheres of pick_radius_px pixels at their depth.
  std::optional<PickResult> best;
  for (const PlacedObject& po : placed_) {
    const pm::Vec3 v = sub(po.anchor, origin);
    const double t = pm::dot(v, d);
    if (t < 0) continue;
    const double radius =
        opt_.pick_radius_px * std::max(view_->depth(po.anchor), view_->camera().near_m) / view_->focal_px();
    const pm::Vec3 off{v.x - t * d.x, v.y - t * d.y, v.z - t * d.z};
    if (pm::dot(off, off) > radius * radius || t > ground_t + radius) continue;
    if (!best || t < best->distance) best = PickResult{po.object, po.anchor, t};
  }
  if (best) return best;
  if (std::isfinite(ground_t))
    return PickResult{
        nullptr, {origin.x + ground_t * d.x, origin.y + ground_t * d.y, origin.z + ground_t * d.z}, ground_t};
  return std::nullopt;
}

std::optional<PickResult> ObjectPlacer::pick_pixel(const TerrainRuntime& rt, double px, double py) const {
  assert(view_ && "pick_pixel() after place()");
  return pick(rt, view_->eye(), view_->pixel_direction(px, py));
}

}  // namespace terralod::blocks
