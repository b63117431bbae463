// A file with a hot rollback journal, made for real: a child process runs `before` (committed),
// then a transaction large enough that SQLite spills it into the file (writing and syncing the
// journal first), and exits without committing. What is left is what a process killed inside a
// rollback-journal transaction leaves; the next read-write connection would roll it back.
//
// Usage (a test linked with SQLite::SQLite3):
//   leave_hot_journal("x.db", "");                 // hot journal over a file that was empty:
//                                                   // what create() killed switching to WAL leaves
//   leave_hot_journal("y.db", "CREATE TABLE t(a)"); // hot journal over a foreign file with a table
#pragma once

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

namespace terralod::test {

inline void leave_hot_journal(const std::string& path, const std::string& before) {
  std::filesystem::remove(path);
  std::filesystem::remove(path + "-journal");
  std::fflush(nullptr);
  const pid_t child = ::fork();
  if (child == 0) {
    sqlite3* db = nullptr;
    if (sqlite3_open(path.c_str(), &db) != SQLITE_OK) ::_exit(2);
    if (!before.empty() && sqlite3_exec(db, before.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK)
      ::_exit(3);
    // A 10-page cache and 400 rows of 1 KB: the transaction spills into the file long before its end.
    const char* spill =
        "PRAGMA journal_mode = DELETE; PRAGMA cache_size = 10; BEGIN; CREATE TABLE spill(b BLOB);"
        "WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < 400) "
        "INSERT INTO spill SELECT randomblob(1000) FROM n;";
    if (sqlite3_exec(db, spill, nullptr, nullptr, nullptr) != SQLITE_OK) ::_exit(4);
    ::_exit(0);  // no COMMIT, no close: the journal stays hot
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the journal child failed: " << status;
  ASSERT_GT(std::filesystem::file_size(path + "-journal"), 0u) << path << ": no journal left";
}

}  // namespace terralod::test
