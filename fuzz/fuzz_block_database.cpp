// libFuzzer target for the block database reader: the input bytes are written to a file, which
// is opened read-only, integrity-checked and read item by item. Every failure must be a
// DatabaseError whose message names the file; anything else (a crash, a sanitizer report,
// another exception, a hang) is a finding.
//
// Bounded work: SQLite reads at most the file's pages, and every list is read once, so one
// run costs O(input size x log) plus SQLite's integrity_check (linear in the file).
// Files: one temporary folder per process (removed at exit), the database and its -wal/-shm
// siblings deleted before every input.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "fuzz_support.hpp"
#include "terralod/blocks/block_database.hpp"
#include "terralod/blocks/object_layers.hpp"

namespace {

namespace fs = std::filesystem;
namespace tb = terralod::blocks;

[[noreturn]] void finding(const std::string& what) { terralod::fuzz::finding("fuzz_block_database", what); }

/// The per-process folder that holds the file under test.
struct TempDir {
  fs::path dir;
  TempDir() {
    dir = fs::temp_directory_path() / ("terralod_fuzz_db_" + std::to_string(::getpid()));
    fs::create_directories(dir);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

void clear(const std::string& path) {
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) fs::remove(path + suffix, ec);
}

/// A DatabaseError must name the file first.
void check_error(const tb::DatabaseError& e, const std::string& path) {
  const std::string_view what = e.what();
  if (!what.starts_with(path + ": ") || what.size() <= path.size() + 2)
    finding("error does not name the file: " + std::string(what));
}

/// Runs `f`, accepting only DatabaseError (checked) as a failure.
template <class F>
void guarded(const std::string& path, F&& f) {
  try {
    f();
  } catch (const tb::DatabaseError& e) {
    check_error(e, path);
  }
}

void read_everything(const std::string& path) {
  const tb::BlockDatabase db = tb::BlockDatabase::open(path, tb::BlockDatabase::Mode::ReadOnly);
  if (db.format_version() < 1 || db.format_version() > tb::BlockDatabase::kFormatVersion)
    finding("opened a database of format version " + std::to_string(db.format_version()));
  const tb::DatabaseInfo& info = db.info();
  if (info.grid_width < 0 || info.grid_height < 0 || info.block_size < 0)
    finding("negative size in the info");

  guarded(path, [&] {
    const auto report = db.check_integrity();
    if (report.ok != report.problems.empty()) finding("integrity report: ok disagrees with its problems");
    for (const std::string& p : report.problems)
      if (!p.starts_with(path + ": ")) finding("integrity problem does not name the file: " + p);
  });
  guarded(path, [&] {
    const std::vector<tb::BlockKey> keys = db.blocks();
    for (std::size_t i = 1; i < keys.size(); ++i)
      if (!(keys[i - 1] < keys[i])) finding("blocks() is not sorted and unique");
    for (tb::BlockKey k : keys)
      guarded(path, [&] {
        if (!db.has_block(k)) finding("a listed block is missing");
        (void)db.read_block(k);
      });
  });
  guarded(path, [&] {
    for (const std::string& name : db.blob_names()) guarded(path, [&] { (void)db.read_blob(name); });
  });
  guarded(path, [&] {
    for (const std::string& layer : db.texture_layers())
      guarded(path, [&] {
        for (const tb::TextureTileKey& t : db.texture_tiles(layer))
          guarded(path, [&] { (void)db.read_texture_tile(layer, t.node, t.level); });
      });
  });
  guarded(path, [&] {
    for (const std::string& key : db.meta_keys()) guarded(path, [&] { (void)db.get_meta(key); });
  });
  guarded(path, [&] {  // object layers: their records, feature blobs and block index
    for (const tb::ObjectLayerInfo& layer : tb::object_layers(db))
      guarded(path, [&] {
        (void)tb::object_features(db, layer.name);
        (void)tb::block_object_features(db, layer.name, {0, 0});
      });
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static TempDir tmp;
  const std::string path = (tmp.dir / "fuzz.db").string();
  clear(path);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
    if (!out) finding("cannot write the temporary file " + path);
  }
  try {
    read_everything(path);
  } catch (const tb::DatabaseError& e) {
    check_error(e, path);
  }
  clear(path);
  return 0;
}
