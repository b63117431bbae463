// terralod texture symbols: the objects of an object layer that its rules draw as symbols,
// rendered level by level into a texture layer (render/symbol_texture.hpp) and stored through
// the same pyramid and tile path as the other computed layers.
#include "texture_symbols.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>
#include <vector>

#include "terralod/blocks/object_layers.hpp"
#include "terralod/blocks/object_placement.hpp"
#include "terralod/pm/json.hpp"
#include "terralod/render/symbol_texture.hpp"
#include "texture_rules.hpp"

namespace terralod::cli {

namespace tb = terralod::blocks;
namespace tr = terralod::render;

int texture_symbols(const Args& a, const std::string& path, const StoreLayer& store) {
  if (!a.has("--objects")) throw UsageError("'texture symbols' needs --objects OBJLAYER");
  tr::SymbolStyle style;
  if (a.has("--color")) {
    const std::optional<tr::Rgba> c = parse_hex_color(a.get("--color"));
    if (!c)
      throw UsageError("option '--color' must be a colour RRGGBB or RRGGBBAA, not '" + a.get("--color") +
                       "'");
    style.color = *c;
  }
  style.diameter_texels = int(a.get_int("--symbol-px", style.diameter_texels, 1, 1000));
  const std::string objects = a.get("--objects");

  auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
  std::vector<std::string> names;
  for (const tb::ObjectLayerInfo& l : tb::object_layers(db)) names.push_back(l.name);
  if (std::find(names.begin(), names.end(), objects) == names.end()) {
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
    throw UsageError(path + ": no object layer '" + objects + "' (" +
                     (names.empty() ? std::string("the database has none") : "it has " + list) + ")");
  }
  auto t = std::chrono::steady_clock::now();
  const tb::ObjectPlacer placer(db, {objects});  // anchors and extents by the placement's rules
  std::vector<tr::SymbolObject> objs;
  for (const tb::MapObject& o : placer.objects())
    objs.push_back({o.anchor, o.extent_m, &placer.rules(o.layer)});
  std::printf("object layer '%s': %zu objects, %s\n", objects.c_str(), objs.size(),
              format_duration(ms_since(t)).c_str());

  const tb::DatabaseInfo& info = db.info();
  const double sample_m = 0.5 * (info.transform.spacing_x() + info.transform.spacing_y());
  tr::LayerRecord rec;
  rec.kind = "symbols";
  rec.source = "terralod texture symbols";
  rec.georef = tr::grid_georef(info.transform, info.grid_width, info.grid_height);
  rec.parameters = strf(
      "{\"objects\": %s, \"color\": [%d, %d, %d, %d], \"symbol_px\": %d, \"sample_m\": %.17g, "
      "\"reference_focal_px\": %.17g, \"reference_gamma_px\": %.17g}",
      pm::json_quote(objects).c_str(), style.color[0], style.color[1], style.color[2], style.color[3],
      style.diameter_texels, sample_m, tr::kSymbolReferenceFocalPx, tr::kSymbolReferenceGammaPx);
  store(db, rec, [&](const std::string& pyr, const tr::PyramidOptions& po) {
    t = std::chrono::steady_clock::now();
    const std::vector<tr::LevelSize> sizes =
        tr::pyramid_levels(info.grid_width, info.grid_height, po.max_texture_size);
    std::vector<std::vector<tr::SymbolPosition>> at;  // each level's symbols, drawn band by band
    for (std::size_t k = 0; k < sizes.size(); ++k) {
      const double texel_m = double(1u << k) * sample_m;
      at.push_back(tr::symbol_positions(objs, rec.georef, sizes[k], texel_m));
      std::printf("level %zu: %d x %d texels of %.4g m, view distance %.6g m: %zu symbols\n", k,
                  sizes[k].width, sizes[k].height, texel_m, tr::symbol_level_distance_m(texel_m),
                  at.back().size());
    }
    tr::ImagePyramid::write_levels(
        info.grid_width, info.grid_height,
        [&](int k, int y, int n, std::uint8_t* rgba) {
          const tr::RgbaImage band =
              tr::render_symbol_rows(at[std::size_t(k)], sizes[std::size_t(k)].width, y, n, style);
          std::copy(band.rgba.begin(), band.rgba.end(), rgba);
        },
        pyr, po);
    std::printf("pyramid of %zu symbol levels -> tiled MIP-mapped TIFF, %s\n", sizes.size(),
                format_duration(ms_since(t)).c_str());
  });
  return 0;
}

}  // namespace terralod::cli
