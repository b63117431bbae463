// terralod texture symbols: a texture layer of the map objects that an object layer's design
// rules draw as 2D symbols (render/symbol_texture.hpp), stored like every computed layer.
#pragma once

#include <functional>
#include <string>

#include "cli_common.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/render/image_pyramid.hpp"
#include "terralod/render/texture_store.hpp"

namespace terralod::cli {

/// Writes a layer's pyramid to the given file with the given options.
using PyramidWriter = std::function<void(const std::string& pyramid_file, const render::PyramidOptions&)>;
/// Stores a computed layer of `db` (cmd_texture.cpp's store_computed: refuses an incomplete
/// database, names the layer from --layer, writes the pyramid through `write`, stores it).
using StoreLayer =
    std::function<void(blocks::BlockDatabase& db, render::LayerRecord& rec, const PyramidWriter& write)>;

/// 'texture symbols DB --layer NAME --objects OBJLAYER [--color RRGGBB[AA]] [--symbol-px N]':
/// options are checked before the database is opened, the object layer before anything is
/// written (UsageError "<db>: no object layer '...'"); on any error the database is unchanged.
int texture_symbols(const Args& a, const std::string& path, const StoreLayer& store);

}  // namespace terralod::cli
