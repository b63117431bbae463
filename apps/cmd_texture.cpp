// terralod texture add|shade|thematic|symbols|export: texture layers of a block database (an
// image, a shading texture or a thematic texture computed from the full-resolution terrain, or
// an object layer's symbols), stored as pyramid and texture-tree tiles.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "terrain_input.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/database_extract.hpp"
#include "terralod/blocks/database_terrain.hpp"
#include "terralod/blocks/image_stretch.hpp"
#include "terralod/blocks/image_warp.hpp"
#include "terralod/blocks/partition.hpp"
#include "terralod/blocks/tree_builder.hpp"
#include "terralod/pm/atomic_file.hpp"
#include "terralod/pm/pm_io.hpp"
#include "terralod/render/gpu_shading.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/terrain_windows.hpp"
#include "terralod/render/texture_store.hpp"
#include "terralod/render/thematic_texture.hpp"
#include "terralod/render/topographic_texture.hpp"
#include "texture_rules.hpp"
#include "texture_symbols.hpp"

namespace terralod::cli {
namespace {

namespace tb = terralod::blocks;
namespace tr = terralod::render;
using Clock = std::chrono::steady_clock;

std::vector<double> parse_list(const Args& a, const std::string& opt, std::size_t n) {
  std::vector<double> v;
  std::stringstream ss(a.get(opt));
  for (std::string item; std::getline(ss, item, ',');) {
    char* end = nullptr;
    const double d = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !std::isfinite(d))
      throw UsageError("option '" + opt + "' must be " + std::to_string(n) +
                       " comma-separated numbers, not '" + a.get(opt) + "'");
    v.push_back(d);
  }
  if (v.size() != n)
    throw UsageError("option '" + opt + "' must be " + std::to_string(n) + " comma-separated numbers, not '" +
                     a.get(opt) + "'");
  return v;
}

tr::TextureConstraints constraints(const Args& a) {
  tr::TextureConstraints c;
  c.max_texture_size = int(a.get_int("--max-texture-size", 1024, 1, 1 << 15));
  c.power_of_two = a.has("--power-of-two");
  return c;
}

// A blocked database whose build was interrupted has no complete tree (nor every block): refuse
// it, as 'terralod extract --db' does, rather than store a layer without its texture tree.
void require_complete_blocks(const tb::BlockDatabase& db) {
  if (db.info().block_size > 0) tb::require_complete_build(db);
}

// Stores the layer from the pyramid file beside the database (the caller removes the file).
void store(tb::BlockDatabase& db, tr::LayerRecord& rec, const std::string& pyramid_path) {
  auto t = Clock::now();
  tr::PyramidOptions po;
  po.max_texture_size = rec.constraints.max_texture_size;
  const tr::ImagePyramid pyr(pyramid_path, po);
  const std::vector<tr::PatchDomain> doms = tr::tree_domains(db);
  {
    ProgressBar bar("texture tiles");
    tr::store_texture_layer(db, rec, pyr, doms, [&](double f) { bar.update(f); });
  }
  const tr::LevelSize l0 = rec.levels.front(), last = rec.levels.back();
  std::printf(
      "store layer '%s': %zu levels (%d x %d -> %d x %d), %zu texture-tree patches of %zu nodes%s, %s\n",
      rec.name.c_str(), rec.levels.size(), l0.width, l0.height, last.width, last.height, rec.patches,
      doms.size(), doms.empty() ? " (no approximation tree in the database)" : "",
      format_duration(ms_since(t)).c_str());
}

std::string pyramid_file(const std::string& db, const std::string& layer) {
  std::string safe;
  for (char c : layer) safe += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return db + ".texture-" + safe + ".tx";
}

// Tells how an image's values became bytes, when they were stretched (image_stretch.hpp).
void print_stretch(const std::string& image, const tb::StretchOptions& s,
                   const std::vector<tb::BandRange>& r) {
  if (r.empty()) return;
  std::string how = s.mode == tb::StretchOptions::Mode::Auto
                        ? tb::describe(tb::StretchOptions{tb::StretchOptions::Mode::Cut})
                        : tb::describe(s);
  std::printf("stretch %s (%s): ", image.c_str(), how.c_str());
  const char* names[3] = {"R", "G", "B"};
  for (std::size_t c = 0; c < r.size(); ++c)
    std::printf("%s%s %.6g..%.6g", c ? ", " : "", names[c], r[c].lo, r[c].hi);
  std::printf(" -> 0..255\n");
}

int texture_add(const Args& a, const std::string& path) {
  if (!a.has("--image")) throw UsageError("'texture add' needs --image FILE");
  tb::StretchOptions stretch;
  try {
    if (a.has("--stretch")) stretch = tb::parse_stretch(a.get("--stretch"));
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
  require_complete_blocks(db);
  tr::LayerRecord rec;
  rec.name = a.get("--layer");
  rec.kind = "image";
  rec.source = a.get("--image");
  rec.constraints = constraints(a);
  if (a.has("--georef")) {
    const std::vector<double> g = parse_list(a, "--georef", 4);
    rec.georef = tr::GeoRect{g[0], g[1], g[2], g[3]};
    if (!(rec.georef.width() > 0 && rec.georef.height() > 0))
      throw UsageError("option '--georef' must be minx,miny,maxx,maxy with minx < maxx and miny < maxy");
  }
  auto t = Clock::now();
  // A georeferenced image (an orthophoto, a map) is warped into the terrain's frame and placed
  // where it lies; any other image covers the terrain.
  const std::string warped = pyramid_file(path, rec.name) + ".warp.tif";
  const pm::FileRemover remove_warped(warped);  // also when the command fails half-way
  std::string image = rec.source;
  if (!a.has("--georef")) {
    int shown = -1;
    const std::optional<tb::WorldImage> w = tb::warp_image_to_terrain(
        rec.source, db, warped,
        [&shown](double f) {
          if (const int pct = int(f * 100.0); pct != shown) std::fprintf(stderr, "\rwarp %3d%%", shown = pct);
        },
        stretch);
    if (w) {
      std::fprintf(stderr, "\r");
      std::printf("warp %s -> the terrain's frame, %d x %d pixels over x %.3f..%.3f, y %.3f..%.3f m, %s\n",
                  rec.source.c_str(), w->width, w->height, w->minx, w->maxx, w->miny, w->maxy,
                  format_duration(ms_since(t)).c_str());
      print_stretch(rec.source, stretch, w->stretched);
      rec.georef = tr::GeoRect{w->minx, w->miny, w->maxx, w->maxy};
      image = warped;
      stretch = tb::StretchOptions{};  // the warped image holds the bytes to draw
      t = Clock::now();
    } else {
      rec.georef = tr::grid_georef(db.info().transform, db.info().grid_width, db.info().grid_height);
    }
  }
  const std::string pyr = pyramid_file(path, rec.name);
  const pm::FileRemover remove_pyramid(pyr);  // when the command ends, also half-way
  tr::PyramidOptions po;
  po.max_texture_size = rec.constraints.max_texture_size;
  {
    ProgressBar bar("pyramid");
    print_stretch(rec.source, stretch,
                  tr::ImagePyramid::convert(
                      image, pyr, po, [&](double f) { bar.update(f); }, stretch));
  }
  std::printf("pyramid %s -> tiled MIP-mapped TIFF, %s\n", rec.source.c_str(),
              format_duration(ms_since(t)).c_str());
  store(db, rec, pyr);
  return 0;
}

// A layer computed from the terrain, one texel per DEM sample: `rec` gets its name and
// constraints from the options; the pyramid goes through a temporary file beside the database,
// written by `write_pyramid(file, options)`.
void store_computed(tb::BlockDatabase& db, const std::string& path, tr::LayerRecord& rec, const Args& a,
                    const std::function<void(const std::string&, const tr::PyramidOptions&)>& write_pyramid) {
  rec.name = a.get("--layer");
  rec.constraints = constraints(a);
  const std::string pyr = pyramid_file(path, rec.name);
  const pm::FileRemover remove_pyramid(pyr);  // when the command ends, also half-way
  tr::PyramidOptions po;
  po.max_texture_size = rec.constraints.max_texture_size;
  write_pyramid(pyr, po);
  store(db, rec, pyr);
}

// The terrain of the database, read window by window (never whole: a continent's texture is
// computed in bands of rows, database_terrain.hpp), and its exact height range.
struct TerrainReader {
  explicit TerrainReader(const tb::BlockDatabase& db) : terrain(db) {
    const auto t = Clock::now();
    {
      ProgressBar bar("heights");
      windows = tr::terrain_windows(terrain, [&](double f) { bar.update(f); });
    }
    std::printf("terrain %d x %d samples from %s, heights %.6g .. %.6g m, %s\n", terrain.width(),
                terrain.height(), db.path().c_str(), windows.lo, windows.hi,
                format_duration(ms_since(t)).c_str());
  }
  tb::DatabaseTerrain terrain;
  tr::TerrainWindows windows;
};

int texture_shade(const Args& a, const std::string& path) {
  auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
  require_complete_blocks(db);
  tr::ShadingOptions so;
  const std::string method =
      a.get_choice("--method", {"lambert", "phong", "multidirectional", "relative"}, "lambert");
  so.method = tr::parse_shading_method(method);
  if (a.has("--light")) {
    const std::vector<double> l = parse_list(a, "--light", 2);
    if (!(l[1] > 0 && l[1] <= 90))
      throw UsageError("option '--light': the altitude must be in (0, 90] degrees");
    so.azimuth_deg = l[0];
    so.altitude_deg = l[1];
  }
  so.shadows = a.has("--shadows");
  if (so.shadows && so.method == tr::ShadingMethod::RelativeHeight)
    throw UsageError("option '--shadows' applies to lit methods only, not to '--method relative'");
  const bool gpu = a.has("--gpu");
  TerrainReader terrain(db);
  tr::TerrainWindows& tw = terrain.windows;
  const tr::WindowMargins m = tr::shading_margins(tw, so);
  tr::LayerRecord rec;
  rec.kind = "shading";
  rec.source = "terralod texture shade";
  rec.georef = tr::grid_georef(terrain.terrain.frame().transform, tw.width, tw.height);
  rec.parameters = strf(
      "{\"method\": \"%s\", \"azimuth_deg\": %.17g, \"altitude_deg\": %.17g, \"shadows\": %s, \"gpu\": %s}",
      method.c_str(), so.azimuth_deg, so.altitude_deg, so.shadows ? "true" : "false", gpu ? "true" : "false");
  // The GPU shades each window as a heightfield of its own (one texture, so no window beyond
  // the GL limit); the CLI's relative shading has a radius (16), never the whole grid's range,
  // which a window alone could not know.
  std::unique_ptr<tr::GlContext> context;
  tr::GpuShadingReport rep;
  int tiles = 0;
  if (gpu) {
    context = tr::create_offscreen_context();
    tw.max_side = 8192;
  }
  const auto band = [&](int y, int n) {
    const tr::TexelRegion r{0, y, -1, n, 1};
    if (!gpu) return tr::grey_to_rgba(tr::shade_terrain(tw, so, r));
    return tr::grey_to_rgba(
        tr::compute_by_windows(tw, r, m, [&](const pm::Heightfield& w, const tr::TexelRegion& in, int, int) {
          tr::FloatRaster f = tr::shade_terrain_gpu(w, so, in, {}, context.get(), &rep);
          tiles += rep.tiles;
          return f;
        }));
  };
  const auto t = Clock::now();
  store_computed(db, path, rec, a, [&](const std::string& pyr, const tr::PyramidOptions& po) {
    {
      ProgressBar bar("shade");
      tr::convert_by_bands(
          tw, band, pyr, po, [&](double f) { bar.update(f); }, "shade");
    }
    const std::string where = gpu ? "gpu (" + rep.renderer + ", " + std::to_string(tiles) + " tiles)" : "cpu";
    std::printf(
        "shade %s, light %.1f/%.1f deg, shadows %s: %d x %d texels on the %s, windows reaching %d/%d/%d/%d "
        "samples left/right/up/down, pyramid written, %s\n",
        method.c_str(), so.azimuth_deg, so.altitude_deg, so.shadows ? "on" : "off", tw.width, tw.height,
        where.c_str(), m.left, m.right, m.top, m.bottom, format_duration(ms_since(t)).c_str());
  });
  return 0;
}

tr::TerrainAttribute thematic_attribute(const Args& a, std::string* name) {
  *name = a.get_choice("--attribute", {"slope", "aspect", "elevation"}, "slope");
  return *name == "slope"    ? tr::TerrainAttribute::SlopeDegrees
         : *name == "aspect" ? tr::TerrainAttribute::AspectDegrees
                             : tr::TerrainAttribute::Elevation;
}

// --rules: every pyramid level drawn by the design rule from the attribute generalised over
// 2^k x 2^k blocks (render_pyramid_levels), instead of box-filtering the colours of level 0.
// Texel size of level k = 2^k x the mean of the x and y sample spacing: symmetric in the two
// axes (a threshold means the same whichever way the grid is turned), the spacing itself on
// square cells, and the mean side of a texel on rectangular ones (x alone would call a
// 30 x 90 m texel 30 m).
void store_thematic_rules(tb::BlockDatabase& db, const std::string& path, const Args& a,
                          const ThematicRules& rules, tr::TerrainAttribute attribute, const std::string& name,
                          const tr::TerrainWindows& tw, tr::LayerRecord& rec) {
  const BuiltRule built = build_rule(rules, attribute, tw.lo, tw.hi);
  const double sample_m = 0.5 * (tw.transform.spacing_x() + tw.transform.spacing_y());
  std::printf("thematic %s, %zu rules from %s, generalise %s, sample %.4g m\n", name.c_str(),
              rules.looks.size(), rules.path.c_str(), rules.generalise.c_str(), sample_m);
  std::vector<std::size_t> level_rules;
  store_computed(db, path, rec, a, [&](const std::string& pyr, const tr::PyramidOptions& po) {
    const auto t = Clock::now();
    const std::vector<tr::LevelSize> sizes = tr::pyramid_levels(tw.width, tw.height, po.max_texture_size);
    for (std::size_t k = 0; k < sizes.size(); ++k) {
      const double texel_m = double(1u << k) * sample_m;
      level_rules.push_back(built.look_for(texel_m));
      std::printf("level %zu: %d x %d texels of %.4g m, rule %zu (%s)\n", k, sizes[k].width, sizes[k].height,
                  texel_m, level_rules.back(),
                  level_rules.back() + 1 == rules.looks.size()
                      ? "far"
                      : strf("max_texel_m %.4g", rules.looks[level_rules.back()].max_texel_m).c_str());
    }
    {
      ProgressBar bar("thematic");
      tr::write_rule_pyramid(tw, attribute, built.rule, sample_m, pyr, po, [&](double f) { bar.update(f); });
    }
    std::printf("pyramid of %zu rendered levels -> tiled MIP-mapped TIFF, %s\n", sizes.size(),
                format_duration(ms_since(t)).c_str());
    rec.parameters = rules_parameters(rules, built, name, sample_m, level_rules);
  });
}

int texture_thematic(const Args& a, const std::string& path) {
  std::optional<ThematicRules> rules;  // checked before the database is opened: a bad file changes nothing
  if (a.has("--rules")) {
    for (const char* o : {"--ramp", "--bands"})
      if (a.has(o))
        throw UsageError(std::string("options '--rules' and '") + o +
                         "' cannot be combined: each rule of the file has its own \"ramp\" and \"bands\"");
    std::string name;
    rules = read_thematic_rules(a.get("--rules"), thematic_attribute(a, &name));
  }
  auto db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadWrite);
  require_complete_blocks(db);
  std::string name;
  const tr::TerrainAttribute attribute = thematic_attribute(a, &name);
  const bool bands = a.has("--bands");
  std::vector<tr::ColorRamp::Stop> stops;  // the given ramp, checked before any work
  if (a.has("--ramp")) stops = parse_ramp(a.get("--ramp"), "option '--ramp'");
  TerrainReader terrain(db);
  const tr::TerrainWindows& tw = terrain.windows;
  tr::LayerRecord rec;
  rec.kind = "thematic";
  rec.source = "terralod texture thematic";
  rec.georef = tr::grid_georef(terrain.terrain.frame().transform, tw.width, tw.height);
  if (rules) {
    store_thematic_rules(db, path, a, *rules, attribute, name, tw, rec);
    return 0;
  }
  const tr::ColorRamp ramp(stops.empty() ? default_ramp(attribute, tw.lo, tw.hi) : stops,
                           bands ? tr::ColorRamp::Mode::Step : tr::ColorRamp::Mode::Linear);
  rec.parameters = strf("{\"attribute\": \"%s\", \"mode\": \"%s\", \"stops\": [%s]}", name.c_str(),
                        bands ? "bands" : "linear", stops_json(ramp).c_str());
  const auto t = Clock::now();
  store_computed(db, path, rec, a, [&](const std::string& pyr, const tr::PyramidOptions& po) {
    {
      ProgressBar bar("thematic");
      const auto band = [&](int y, int n) {
        return tr::apply_mapper(tr::terrain_attribute(tw, attribute, {0, y, -1, n, 1}), ramp);
      };
      tr::convert_by_bands(
          tw, band, pyr, po, [&](double f) { bar.update(f); }, "thematic");
    }
    std::printf("thematic %s, %zu %s: %d x %d texels, pyramid written, %s\n", name.c_str(),
                ramp.stops().size(), bands ? "bands" : "ramp stops", tw.width, tw.height,
                format_duration(ms_since(t)).c_str());
  });
  return 0;
}

int texture_export(const Args& a, const std::string& path) {
  if (!a.has("--out")) throw UsageError("'texture export' needs --out FILE.tif|FILE.png");
  const auto db = tb::BlockDatabase::open(path);
  const tr::LayerRecord rec = tr::read_layer_record(db, a.get("--layer"));
  const int level = int(a.get_int("--level", 0, 0, 1000));
  if (level >= int(rec.levels.size()))
    throw UsageError(
        strf("option '--level': layer '%s' has levels 0..%zu", rec.name.c_str(), rec.levels.size() - 1));
  auto t = Clock::now();
  {
    ProgressBar bar("export");
    tr::export_layer_level(db, rec, level, a.get("--out"), [&](double f) { bar.update(f); });
  }
  const tr::LevelSize size = rec.levels[std::size_t(level)];
  std::printf("export layer '%s' level %d: %d x %d pixels -> %s, %s\n", rec.name.c_str(), level, size.width,
              size.height, a.get("--out").c_str(), format_duration(ms_since(t)).c_str());
  return 0;
}

}  // namespace

CommandSpec texture_spec() {
  CommandSpec s;
  s.name = "texture";
  s.positionals = "add|shade|thematic|symbols|export DB";
  s.min_positionals = s.max_positionals = 2;
  s.summary =
      "Add, compute (topographic shading, thematic maps) or export texture layers of a block database.";
  s.description =
      "A texture layer is an image pyramid (levels halving down to --max-texture-size) plus a\n"
      "texture tree mirroring the database's approximation tree: each node gets the sub-image of\n"
      "the finest level that covers its domain within the maximum texture size. Both are stored\n"
      "as tiles in the database; the layer's description is JSON metadata.\n"
      "  add     --layer NAME --image FILE [--georef minx,miny,maxx,maxy]: any image OpenImageIO\n"
      "          reads, any size (converted through a tiled MIP-mapped file, never all in memory).\n"
      "          A georeferenced image (an orthophoto or map GDAL reads with a CRS: grey,\n"
      "          RGB, RGBA or a colour table; or a scan placed by ground control points, first\n"
      "          warped north-up) is warped into the terrain's frame (bilinear, at about its own\n"
      "          resolution, transparent beyond it) and placed where it lies;\n"
      "          another image covers the terrain, one texel per sample at its full size.\n"
      "          --georef places either on that world box instead. A band is alpha only where\n"
      "          the image marks it so (RGB + near infrared draws as opaque RGB); the colour is\n"
      "          the first three other bands, or the first one as grey.\n"
      "          --stretch S: how values become 8-bit texels: auto (default: 8-bit images as they\n"
      "          are; 16-bit, 32-bit and floating-point ones each colour band's 2% cut: the values\n"
      "          at its 2nd percentile and below black, at its 98th and above full, linear\n"
      "          between, over the pixels that are not transparent or nodata; one more read of\n"
      "          the image, two for 32-bit and floating point), P% (that cut at P percent),\n"
      "          LO,HI (those values to 0 and 255 in every band) or none (the type's whole\n"
      "          range: 0..65535 for unsigned 16 bits, 0..1 for floating point). The ranges used\n"
      "          are printed. Alpha is never stretched.\n"
      "  shade   --layer NAME [--light AZ,ALT] [--shadows] [--method M] [--gpu]: a shading texture\n"
      "          of the full-resolution terrain, one texel per DEM sample (azimuth clockwise from\n"
      "          north, altitude above the horizon, default 315,45; lambert without shadows is the\n"
      "          conventional GIS hillshade); --gpu renders it offscreen through OSMesa.\n"
      "  thematic --layer NAME [--attribute slope|aspect|elevation] [--ramp V:RRGGBB,...] [--bands]:\n"
      "          a thematic texture, one texel per DEM sample: slope (degrees), aspect (degrees\n"
      "          clockwise from north, facing downhill; flat ground transparent) or elevation\n"
      "          (metres) through a colour ramp (linear between stops, or constant bands with\n"
      "          --bands; below the first band transparent). Default ramps: slope white to red\n"
      "          at 45 deg, aspect around the compass, elevation green-brown-white over the range.\n"
      "          --rules FILE.json instead of --ramp/--bands: design rules by level of detail.\n"
      "          Level k is drawn from the attribute generalised over 2^k x 2^k samples (nearest,\n"
      "          majority or mean; default mean, nearest for aspect), by the first rule whose\n"
      "          max_texel_m is >= its texel size (2^k x the mean x/y sample spacing, metres), else\n"
      "          by the last rule: {\"generalise\": \"mean\", \"rules\": [{\"max_texel_m\": 60,\n"
      "          \"ramp\": \"0:ffffff,45:a00000\", \"bands\": true}, {\"ramp\": \"0:ffffff,45:606060\"}]}.\n"
      "          shade and thematic read the terrain from the blocks window by window, in bands of\n"
      "          rows (never whole: a 128 MiB cache of decoded blocks, windows of about 4 M samples\n"
      "          widened by what shadows reach; --rules: every level by windows too), after one\n"
      "          pass for its exact height range.\n"
      "  symbols --layer NAME --objects OBJLAYER [--color RRGGBB[AA]] [--symbol-px N]: the objects of\n"
      "          the object layer OBJLAYER that its design rules draw as \"symbol\", as discs of N\n"
      "          texels (default 7) in the colour (default c81e1e) with a 1-texel dark outline at\n"
      "          each object's anchor, anti-aliased, on a transparent layer. Level k (texels of\n"
      "          t_k = 2^k x the mean x/y sample spacing) shows the objects the rules draw as\n"
      "          symbols at d_k = t_k x 623.5 / sqrt(1) metres, the distance at which a 1280 x 720,\n"
      "          60 deg view (focal 623.5 px) sees one texel as gamma = 1 pixel (screen-size rules:\n"
      "          the object's extent at d_k). Symbols keep their size in texels at every level.\n"
      "  export  --layer NAME [--level K] --out FILE.tif|FILE.png: pyramid level K (0 = full size).";
  s.options = {
      {"--layer", "NAME", "texture layer name", true},
      {"--image", "FILE", "add: the image"},
      {"--georef", "BOX", "add: minx,miny,maxx,maxy world extent of the image (metres)"},
      {"--stretch", "S", "add: auto (default), P%, LO,HI or none: how values become 8-bit texels"},
      {"--light", "AZ,ALT", "shade: light azimuth and altitude, degrees (default 315,45)"},
      {"--shadows", "", "shade: cast shadows against the full-resolution terrain"},
      {"--method", "M", "shade: lambert (default), phong, multidirectional or relative"},
      {"--gpu", "", "shade: compute on the GPU (OSMesa offscreen)"},
      {"--attribute", "A", "thematic: slope (default), aspect or elevation"},
      {"--ramp", "STOPS", "thematic: colour stops V:RRGGBB[AA],... (values increasing)"},
      {"--bands", "", "thematic: constant colour bands between the stops"},
      {"--rules", "FILE", "thematic: JSON design rules by level of detail (not with --ramp/--bands)"},
      {"--objects", "OBJLAYER", "symbols: the object layer whose symbols are drawn"},
      {"--color", "RRGGBB[AA]", "symbols: symbol colour (default c81e1e, opaque)"},
      {"--symbol-px", "N", "symbols: symbol diameter in texels, >= 1 (default 7)"},
      {"--max-texture-size", "N",
       "add/shade/thematic/symbols: renderer texture limit, pixels (default 1024)"},
      {"--power-of-two", "", "add/shade/thematic/symbols: texture-tree patches of power-of-two sizes"},
      {"--level", "K", "export: pyramid level (default 0)"},
      {"--out", "FILE", "export: output .tif or .png"},
  };
  return s;
}

int cmd_texture(const Args& a) {
  const std::string verb = a.positionals()[0], path = a.positionals()[1];
  if (verb == "add") return texture_add(a, path);
  if (verb == "shade") return texture_shade(a, path);
  if (verb == "thematic") return texture_thematic(a, path);
  if (verb == "symbols")
    return texture_symbols(a, path,
                           [&](tb::BlockDatabase& db, tr::LayerRecord& rec, const PyramidWriter& write) {
                             require_complete_blocks(db);
                             store_computed(db, path, rec, a, write);
                           });
  if (verb == "export") return texture_export(a, path);
  throw UsageError("unknown action '" + verb + "' (add, shade, thematic, symbols or export)");
}

}  // namespace terralod::cli
