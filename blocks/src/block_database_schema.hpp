// The block database's info row as the schema stores it (private to its files): read back and
// verified against its checksum, for open() and for check_integrity().
#pragma once

#include "block_database_connection.hpp"

namespace terralod::blocks::detail {

/// Reads and verifies the info row into `info` and `format_version`; DatabaseError naming the
/// problem (no row, several rows, a bad field, a newer format version, a checksum mismatch).
void read_info(BlockDatabaseImpl& d, DatabaseInfo& info, int& format_version);

}  // namespace terralod::blocks::detail
