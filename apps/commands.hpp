// The terralod subcommands defined outside terralod.cpp: each file apps/cmd_<name>.cpp defines
// its spec (what --help prints and the parser accepts) and its entry point; terralod.cpp
// registers them in commands().
#pragma once

#include <string>
#include <vector>

#include "cli_common.hpp"

namespace terralod::cli {

// One pair per command file, in the order they were added.
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
// terralod view --db hybrid.db (cmd_hybrid_view.cpp); c = X,Y,Z,YAW,PITCH,FOVY as parsed by view.
int view_hybrid(const std::string& db_path, const std::vector<double>& c, double tau, int width, int height,
                const std::string& out_png, const std::string& dump_mesh, bool wireframe);

// terralod view --db terrain.db (cmd_view_db.cpp): one frame of the block database's runtime,
// with --layer textures per patch; c = X,Y,Z,YAW,PITCH,FOVY as parsed by view.
int view_blocks(const Args& a, const std::vector<double>& c, double tau, int width, int height);

CommandSpec export_spec();
int cmd_export(const Args&);

CommandSpec testdem_spec();
int cmd_testdem(const Args&);

// Defined only when the benchmarks are built (TERRALOD_HAVE_BENCH; bench/CMakeLists.txt adds it).
CommandSpec bench_spec();
int cmd_bench(const Args&);

}  // namespace terralod::cli
