// The terralod subcommands: each file apps/cmd_<name>.cpp defines its spec (what --help prints
// and the parser accepts) and its entry point; terralod.cpp registers them in commands().
#pragma once

#include <string>

#include "cli_common.hpp"
#include "terralod/pm/view.hpp"

namespace terralod::cli {

// One pair per command file, in the order they were added.
CommandSpec pm_spec();
int cmd_pm(const Args&);

CommandSpec extract_spec();
int cmd_extract(const Args&);

CommandSpec info_spec();
int cmd_info(const Args&);

CommandSpec demo_spec();
int cmd_demo(const Args&);

CommandSpec generate_spec();
int cmd_generate(const Args&);

CommandSpec view_spec();
int cmd_view(const Args&);

CommandSpec build_spec();
int cmd_build(const Args&);

CommandSpec tin_spec();
int cmd_tin(const Args&);

CommandSpec texture_spec();
int cmd_texture(const Args&);

CommandSpec fly_spec();
int cmd_fly(const Args&);

CommandSpec hybrid_spec();
int cmd_hybrid(const Args&);
int cmd_extract_hybrid(const Args&);          // terralod extract --db hybrid.db --grid-level L
int info_hybrid(const std::string& db_path);  // terralod info hybrid.db
// terralod view --db hybrid.db (cmd_hybrid_view.cpp); camera as parsed by view (view_camera.hpp:
// no clip planes yet, the image size in width_px x height_px).
int view_hybrid(const std::string& db_path, const pm::Camera& camera, double tau, const std::string& out_png,
                const std::string& dump_mesh, bool wireframe);

// terralod view --db terrain.db (cmd_view_db.cpp): one frame of the block database's runtime,
// with --layer textures per patch; camera as for view_hybrid.
int view_blocks(const Args& a, const pm::Camera& camera, double tau);

CommandSpec export_spec();
int cmd_export(const Args&);

CommandSpec testdem_spec();
int cmd_testdem(const Args&);

CommandSpec objects_spec();
int cmd_objects(const Args&);

// Defined only when the benchmarks are built (TERRALOD_HAVE_BENCH; bench/CMakeLists.txt adds it).
CommandSpec bench_spec();
int cmd_bench(const Args&);

}  // namespace terralod::cli
