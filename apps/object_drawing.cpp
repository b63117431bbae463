// Draws the map objects placed this frame (see object_drawing.hpp).
#include "object_drawing.hpp"

#include <cmath>
#include <map>

#include "cli_common.hpp"
#include "terralod/blocks/object_drape.hpp"
#include "terralod/pm/timing.hpp"

namespace terralod::cli {

namespace {

// Colours: buildings a light stone, draped lines a dark blue-grey that reads on any terrain.
const glm::vec4 kShapeColour{0.86f, 0.80f, 0.70f, 1.0f};
const glm::vec4 kLineColour{0.16f, 0.22f, 0.34f, 1.0f};

}  // namespace

std::string drawn_line(const ObjectDrawStats& s, bool timings) {
  return strf("drawn: %zu icons, %zu of %zu labels, %zu line and %zu shape triangles", s.icons,
              s.labels_shown, s.label_candidates, s.line_triangles, s.shape_triangles) +
         (timings ? strf(" (%.2f ms CPU)", s.cpu_ms) : std::string());
}

ObjectDrawing::ObjectDrawing(render::GlContext& ctx, const blocks::ObjectPlacer& placer)
    : renderer_(ctx), shapes_(placer) {
  std::map<std::pair<std::string, int>, render::IconStyleId> loaded;  // one style per image and quads
  for (std::size_t l = 0; l < placer.layers().size(); ++l) {
    const blocks::ObjectRules& r = placer.rules(l);
    const auto key = std::pair{r.icon_image(), r.icon_quads()};
    auto it = loaded.find(key);
    if (it == loaded.end())
      it = loaded
               .emplace(key, r.icon_image().empty()
                                 ? renderer_.add_icon_style(render::default_marker_image(), r.icon_quads())
                                 : renderer_.load_icon_style(r.icon_image(), r.icon_quads()))
               .first;
    icon_style_.push_back(it->second);
  }
}

ObjectDrawStats ObjectDrawing::draw(render::FrameSource& frame, const blocks::ObjectPlacer& placer,
                                    const blocks::TerrainRuntime& rt, const pm::View& view) {
  const double t0 = pm::thread_cpu_ms();
  ObjectDrawStats s;
  const pm::Camera& cam = view.camera();
  if (!declutter_ || declutter_w_ != cam.width_px || declutter_h_ != cam.height_px) {  // a new screen
    declutter_ = std::make_unique<blocks::LabelDeclutterer>(
        blocks::LabelDeclutterOptions{.screen_width = cam.width_px, .screen_height = cam.height_px});
    declutter_w_ = cam.width_px, declutter_h_ = cam.height_px;
  }
  icons_.clear();
  candidates_.clear();
  labels_.clear();
  lines_.clear();
  shape_objects_.clear();
  std::vector<const blocks::PlacedObject*> label_of;  // per candidate
  for (const blocks::PlacedObject& p : placer.placed()) {
    const blocks::MapObject& m = *p.object;
    const blocks::ObjectRules& rules = placer.rules(m.layer);
    const glm::dvec3 anchor{p.anchor.x, p.anchor.y, p.anchor.z};
    switch (p.draw) {
      case blocks::Representation::Icon:
        icons_.push_back({anchor, icon_style_[m.layer], rules.icon_size_m()});
        break;
      case blocks::Representation::Label: {
        double px = 0, py = 0;
        if (!m.named || !view.project(p.anchor, px, py)) break;  // unnamed: no label
        const int size = std::max(1, int(std::lround(rules.label_size_px())));
        const render::PixelBox r = renderer_.label_rect({px, py}, m.name, size);
        if (r.empty()) break;
        candidates_.push_back({{std::uint32_t(m.layer), m.feature.id},
                               float(r.x0),
                               float(r.y0),
                               float(r.x1),
                               float(r.y1),
                               m.priority,
                               float(p.distance)});
        label_of.push_back(&p);
        break;
      }
      case blocks::Representation::Shape:
        if (m.feature.geometry == blocks::GeometryType::Polygon) {
          shape_objects_.push_back(p);
          break;
        }
        [[fallthrough]];  // a shape rule on lines: drawn as the line (add_object_layer refuses points)
      case blocks::Representation::Line: {
        const auto object = std::uint32_t(&m - placer.objects().data());
        for (const std::vector<blocks::WorldPoint>& ring : m.feature.rings) {
          if (m.feature.geometry != blocks::GeometryType::Polygon) {
            blocks::drape_line(rt, ring, rules.line_width_m(), object, lines_);
            continue;
          }
          ring_ = ring;  // a polygon's outline: its rings closed
          if (!ring_.empty()) ring_.push_back(ring_.front());
          blocks::drape_line(rt, ring_, rules.line_width_m(), object, lines_);
        }
        break;
      }
      case blocks::Representation::Symbol:  // in its texture layer ('terralod texture symbols')
      case blocks::Representation::None:
        break;
    }
  }
  s.label_candidates = candidates_.size();
  if (!candidates_.empty()) {
    std::map<blocks::LabelId, std::size_t> index;
    for (std::size_t k = 0; k < candidates_.size(); ++k) index.emplace(candidates_[k].id, k);
    for (const blocks::LabelId& id : declutter_->update(candidates_)) {
      const blocks::PlacedObject& p = *label_of[index.at(id)];
      const blocks::ObjectRules& rules = placer.rules(p.object->layer);
      labels_.push_back({{p.anchor.x, p.anchor.y, p.anchor.z},
                         p.object->name,
                         std::max(1, int(std::lround(rules.label_size_px())))});
    }
  }
  shapes_mesh_.clear();
  if (!shape_objects_.empty()) shapes_.extrude(rt, shape_objects_, shapes_mesh_);
  s.cpu_ms = pm::thread_cpu_ms() - t0;
  // Solids first, then ribbons on the terrain, icons, and the labels over everything.
  if (!shapes_mesh_.empty())
    s.shape_triangles = renderer_.draw_mesh(frame, shapes_mesh_, kShapeColour).objects;
  if (!lines_.empty())
    s.line_triangles = renderer_.draw_mesh(frame, lines_, kLineColour, {.on_terrain = true}).objects;
  if (!icons_.empty()) s.icons = renderer_.draw_icons(frame, icons_).objects;
  if (!labels_.empty()) {
    renderer_.draw_labels(frame, labels_);
    s.labels_shown = labels_.size();
  }
  return s;
}

}  // namespace terralod::cli
