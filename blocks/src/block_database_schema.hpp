// The block database's info row as the schema stores it (private to its files): read back and
// verified against its checksum, for open() and for check_integrity().
#pragma once

#include "block_database_connection.hpp"

namespace terralod::blocks::detail {

/// Reads and verifies the info row into `info` and `format_version`; DatabaseError naming the
/// problem (no row, several rows, a bad field, a newer format version, a checksum mismatch).
void read_info(BlockDatabaseImpl& d, DatabaseInfo& info, int& format_version);

/// Whether the object-layer tables exist (object_layers.hpp): false when none of them does, true
/// when all three are real tables with the expected columns; DatabaseError "schema mismatch ..."
/// for anything in between (a missing one, a view, a missing column).
bool object_tables_exist(BlockDatabaseImpl& d);
/// Creates the object-layer tables unless they exist (inside the caller's transaction).
void create_object_tables(BlockDatabaseImpl& d);

}  // namespace terralod::blocks::detail
