// libFuzzer target for the mesh readers (pm::read_mesh: PLY in ascii / little- / big-endian,
// Wavefront OBJ): arbitrary file contents must give either a sound mesh or a
// std::runtime_error naming the file.
//
// Input layout: byte 0 picks the extension (bit 0: 0 = mesh.ply, 1 = mesh.obj), the rest is the
// file's contents, written to a private temporary folder.
//
// A finding is anything but a std::runtime_error whose message starts with the path: a crash,
// a sanitizer report, another exception type (including std::bad_alloc: counts must be checked
// against the file before allocating), a coordinate that is not finite, a triangle index out
// of range, or a mesh that does not survive write_mesh (binary PLY) and read_ply bit for bit.
//
// Bounded work: inputs over 64 KiB are skipped (returning -1 keeps them out of the corpus).
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "terralod/pm/mesh_io.hpp"

namespace {

namespace fs = std::filesystem;
namespace pm = terralod::pm;

[[noreturn]] void finding(const std::string& what) { terralod::fuzz::finding("fuzz_mesh_reader", what); }
#define REQUIRE(cond)                                 \
  do {                                                \
    if (!(cond)) finding("invariant broken: " #cond); \
  } while (0)

fs::path scratch_dir;

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  char tmpl[] = "/tmp/fuzz_mesh_reader.XXXXXX";
  if (const char* d = ::mkdtemp(tmpl))
    scratch_dir = d;
  else
    finding("cannot create a temporary folder");
  std::atexit([] {
    std::error_code ec;
    fs::remove_all(scratch_dir, ec);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 || size > 65536) return -1;
  const std::string path = (scratch_dir / ((data[0] & 1) ? "mesh.obj" : "mesh.ply")).string();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data + 1), std::streamsize(size - 1));
    if (!out) finding("cannot write " + path);
  }
  pm::TriangleMeshData m;
  try {
    m = pm::read_mesh(path);
  } catch (const std::runtime_error& e) {
    REQUIRE(std::string_view(e.what()).starts_with(path + ": "));
    return 0;
  } catch (const std::exception& e) {
    finding(std::string("unexpected exception: ") + e.what());
  }
  for (const auto& p : m.positions)
    for (const double c : p) REQUIRE(std::isfinite(c));
  for (const auto& t : m.triangles)
    for (const std::uint32_t v : t) REQUIRE(v < m.positions.size());
  const std::string again = (scratch_dir / "again.ply").string();
  pm::write_mesh(m, again);
  const pm::TriangleMeshData back = pm::read_ply(again);
  REQUIRE(back.positions == m.positions);
  REQUIRE(back.triangles == m.triangles);
  return 0;
}
