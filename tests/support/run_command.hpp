// Test support for end-to-end tests of the command-line tools: run a command line capturing its
// standard output and error and its exit status, and scratch folders of this process's own.
//
// Usage:
//   terralod::test::TempDir dir("cli");                          // TERRALOD_TEST_TMP/cli-<pid>-<n>
//   const auto r = terralod::test::run_command(terralod::test::quote(TERRALOD_CLI) + " info " +
//                                              terralod::test::quote((dir.path() / "x.pm").string()));
//   EXPECT_EQ(r.status, 1) << r.err;                             // removed when `dir` goes out of scope
//
// Contract:
//   run_command(cmd, options)
//     cmd      a /bin/sh command line, arguments already shell-quoted (quote() below); its stdin is
//              /dev/null. Runs to its end (no timeout: the ctest TIMEOUT bounds a hang).
//     returns  status: the exit code, or -1 when the command did not exit normally (killed by a
//              signal, or the shell could not be started); out / err: everything written to
//              stdout / stderr (err also holds stdout when options.merge_stderr).
//     The streams are captured in files named after this process's id and a per-process counter
//     in TERRALOD_TEST_TMP, removed before returning: tests of one executable that ctest runs as
//     parallel processes never share a capture file. Thread-safe.
//   run_tool(exe, args, options)  run_command of the executable `exe` (quoted here) and `args`.
//   TempDir(prefix)  creates TERRALOD_TEST_TMP/<prefix>-<pid>-<n> (n counts the TempDirs of this
//              process), empty; the destructor removes it and everything in it. Movable, not
//              copyable. A process-wide one for tests that share files across test cases:
//              process_temp_dir(prefix) (created on first use, removed at exit).
//   shared_file(name, build)  a file shared by every process of this test executable (ctest runs
//              each test case as a process of its own): the first process to ask builds it with
//              build(path) at a private path and hard-links it into place; the others wait for
//              it (a lock file beside it) and reuse it.
//              For deterministic fixtures that are expensive to make (a block database) and only
//              read by the tests. Keyed by the executable's name, size and modification time, so
//              a rebuilt executable never reads what an older build wrote (older keys are removed).
//   quote(s)   s as one single-quoted /bin/sh word (embedded quotes escaped).
//   slurp(p)   the bytes of file p ("" when it cannot be read).
//   lines_of(s) s split at '\n' (no trailing empty line).
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace terralod::test {

struct CommandResult {
  int status = -1;       ///< exit code; -1 when the command did not exit normally
  std::string out, err;  ///< captured standard output and error
};

struct RunOptions {
  bool merge_stderr = false;  ///< send stdout into err as well (one interleaved stream)
  bool no_display = false;    ///< unset DISPLAY and WAYLAND_DISPLAY (headless GL paths)
};

CommandResult run_command(const std::string& command_line, const RunOptions& options = {});

/// run_command(quote(executable) + " " + args, options): one of the built tools (TERRALOD_CLI,
/// TERRALOD_FLY) with its arguments, already shell-quoted where needed.
CommandResult run_tool(const std::string& executable, const std::string& args,
                       const RunOptions& options = {});

class TempDir {
 public:
  explicit TempDir(const std::string& prefix);
  ~TempDir();
  TempDir(TempDir&& other) noexcept;
  TempDir& operator=(TempDir&&) = delete;
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

/// A folder of this process's own shared by all its tests, removed when the process exits
/// normally (a function-local static TempDir). The prefix of the first call names it.
const std::filesystem::path& process_temp_dir(const std::string& prefix);

/// TERRALOD_TEST_TMP/shared-<executable>-<key>/<name>, built by `build` unless another process of
/// the same executable already made it. `build` must write exactly the file it is given (it may
/// also leave nothing else behind) and must be deterministic: which process wins does not matter.
std::filesystem::path shared_file(const std::string& name,
                                  const std::function<void(const std::filesystem::path&)>& build);

std::string quote(const std::string& s);
std::string slurp(const std::filesystem::path& p);
std::vector<std::string> lines_of(const std::string& s);

}  // namespace terralod::test
