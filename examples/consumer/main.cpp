// Uses an installed terralod: builds a block database of a generated terrain, opens it and
// extracts the whole terrain as one watertight mesh within 5 m.
#include <cstdio>
#include <filesystem>
#include <string>
#include <terralod/blocks/database_extract.hpp>
#include <terralod/blocks/tree_builder.hpp>
#include <terralod/pm/terrain_generator.hpp>

int main() {
  namespace fs = std::filesystem;
  terralod::pm::TerrainOptions terrain;
  terrain.width = terrain.height = 129;
  const terralod::pm::Heightfield hf = terralod::pm::generate_terrain(terrain);

  const std::string path = (fs::temp_directory_path() / "terralod-consumer.db").string();
  for (const std::string& f : {path, path + "-wal", path + "-shm"}) fs::remove(f);
  terralod::blocks::DatabaseBuildOptions build;
  build.block_size = 65;  // 2 x 2 blocks
  const terralod::blocks::DatabaseSummary summary = terralod::blocks::build_database(hf, path, build);

  const terralod::blocks::ExtractedMesh m = terralod::blocks::extract_mesh(path, /*max_error=*/5.0);
  std::printf("consumer: %zu blocks, %zu triangles within %.3g m (measured) of the 129 x 129 terrain\n",
              summary.blocks, m.mesh.triangles.size(), m.measured_error);
  for (const std::string& f : {path, path + "-wal", path + "-shm"}) fs::remove(f);
  return m.measured_error <= 5.0 && !m.mesh.triangles.empty() ? 0 : 1;
}
