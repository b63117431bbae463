// The block database's integrity check: SQLite's structural check, every stored blob's size and
// CRC-32 (object features included), and the info row against its checksum, each problem
// reported rather than thrown.
//
// Memory: one row at a time (each table is streamed in one read transaction).
#include <sqlite3.h>

#include <cassert>
#include <string>

#include "block_database_connection.hpp"
#include "block_database_schema.hpp"
#include "terralod/blocks/block_database.hpp"

namespace terralod::blocks {

namespace {

using detail::blob_item;
using detail::block_name;
using detail::OneOff;
using detail::read_info;
using detail::tile_name;

}  // namespace

BlockDatabase::IntegrityReport BlockDatabase::check_integrity() const {
  assert(impl_);
  Impl& d = *impl_;
  IntegrityReport report;
  const auto problem = [&](const std::string& p) { report.problems.push_back(d.path + ": " + p); };

  // SQLite's own structural check (b-trees, free list, indexes, NOT NULL), at most 100 messages.
  try {
    OneOff st(d, "PRAGMA integrity_check(100)", "integrity_check");
    for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
      if (rc != SQLITE_ROW) d.check(rc, "integrity_check failed");
      const auto* msg = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
      const std::string m = msg ? msg : "(null)";
      if (m != "ok") problem("sqlite integrity_check: " + m);
    }
  } catch (const DatabaseError& e) {
    report.problems.push_back(e.what());
  }

  // Every blob: size and checksum. Each table is one read transaction, streamed row by row.
  struct Scan {
    const char* sql;
    int first_blob_column;
    std::string (*name)(sqlite3_stmt*);
    bool object_table;  // exists only once an object layer was added
  };
  const Scan scans[] = {
      {"SELECT col, row, size, crc32, data FROM blocks ORDER BY col, row", 2,
       [](sqlite3_stmt* s) {
         return block_name({sqlite3_column_int(s, 0), sqlite3_column_int(s, 1)});
       },
       false},
      {"SELECT name, size, crc32, data FROM blobs ORDER BY name", 1,
       [](sqlite3_stmt* s) {
         const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
         return blob_item(p ? p : "");
       },
       false},
      {"SELECT layer, node, level, size, crc32, data FROM texture_tiles ORDER BY layer, node, level", 3,
       [](sqlite3_stmt* s) {
         const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
         return tile_name(p ? p : "", sqlite3_column_int64(s, 1), sqlite3_column_int(s, 2));
       },
       false},
      {"SELECT layer, id, size, crc32, data FROM object_features ORDER BY layer, id", 2,
       [](sqlite3_stmt* s) {
         const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
         return "object layer '" + std::string(p ? p : "") + "': feature " +
                std::to_string(sqlite3_column_int64(s, 1));
       },
       true},
  };
  bool objects = false;
  try {
    objects = detail::object_tables_exist(d);
  } catch (const DatabaseError& e) {
    report.problems.push_back(e.what());
  }
  for (const Scan& scan : scans) {
    if (scan.object_table && !objects) continue;
    try {
      OneOff st(d, scan.sql, "cannot scan the blobs");
      for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
        if (rc != SQLITE_ROW) d.check(rc, "scan stopped");
        ++report.items_checked;
        const std::string p = d.verify(st, scan.first_blob_column, nullptr);
        if (!p.empty()) problem(scan.name(st) + ": " + p);
      }
    } catch (const DatabaseError& e) {
      report.problems.push_back(e.what());
    }
  }
  // Object layers: each layer's feature count, and every block index entry naming a feature.
  if (objects) {
    try {
      OneOff st(
          d,
          "SELECT l.name, l.feature_count, (SELECT count(*) FROM object_features f WHERE f.layer = l.name) "
          "FROM object_layers l ORDER BY l.name",
          "cannot scan the object layers");
      for (int rc; (rc = sqlite3_step(st)) != SQLITE_DONE;) {
        if (rc != SQLITE_ROW) d.check(rc, "scan stopped");
        const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
        if (sqlite3_column_int64(st, 1) != sqlite3_column_int64(st, 2))
          problem("object layer '" + std::string(p ? p : "") +
                  "': " + std::to_string(sqlite3_column_int64(st, 1)) + " features recorded, " +
                  std::to_string(sqlite3_column_int64(st, 2)) + " stored");
      }
      OneOff idx(
          d,
          "SELECT b.layer, b.col, b.row, b.feature FROM object_blocks b WHERE NOT EXISTS (SELECT 1 FROM "
          "object_features f WHERE f.layer = b.layer AND f.id = b.feature) LIMIT 100",
          "cannot scan the object block index");
      for (int rc; (rc = sqlite3_step(idx)) != SQLITE_DONE;) {
        if (rc != SQLITE_ROW) d.check(rc, "scan stopped");
        const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(idx, 0));
        problem("object layer '" + std::string(p ? p : "") +
                "': " + block_name({sqlite3_column_int(idx, 1), sqlite3_column_int(idx, 2)}) +
                " lists feature " + std::to_string(sqlite3_column_int64(idx, 3)) + ", which is not stored");
      }
    } catch (const DatabaseError& e) {
      report.problems.push_back(e.what());
    }
  }
  // The info row (re-read: its checksum covers every field).
  try {
    DatabaseInfo now;
    int version = 0;
    read_info(d, now, version);
    if (!(now == d.info) || version != d.format_version)
      problem("info: changed since the database was opened");
  } catch (const DatabaseError& e) {
    report.problems.push_back(e.what());
  }
  report.ok = report.problems.empty();
  return report;
}

}  // namespace terralod::blocks
