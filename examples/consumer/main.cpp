// Builds a PM of a generated terrain with the installed library and extracts it at 5 m.
#include <cstdio>

#include <terralod/pm/progressive_mesh.hpp>
#include <terralod/pm/terrain_generator.hpp>

int main() {
  terralod::pm::TerrainOptions terrain;
  terrain.width = terrain.height = 65;
  const terralod::pm::Heightfield hf = terralod::pm::generate_terrain(terrain);
  const terralod::pm::ProgressiveMesh pm = terralod::pm::ProgressiveMesh::build(hf);
  const terralod::pm::TriangleMesh mesh = pm.extract(/*max_error=*/5.0);
  std::printf("consumer: %zu triangles within %.3g m of the 65 x 65 terrain\n", mesh.triangles.size(),
              mesh.error_bound);
  return mesh.error_bound <= 5.0 && !mesh.triangles.empty() ? 0 : 1;
}
