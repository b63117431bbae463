// Test support: runs command lines capturing their streams and exit status, and per-process
// scratch folders (see run_command.hpp).
#include "run_command.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <system_error>

namespace terralod::test {

namespace fs = std::filesystem;

namespace {

/// A name unique within the machine's running processes: "<prefix>-<pid>-<n>".
std::string unique_name(const std::string& prefix) {
  static std::atomic<unsigned> counter{0};
  return prefix + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
}

fs::path test_tmp_root() {
  const fs::path root(TERRALOD_TEST_TMP);
  fs::create_directories(root);
  return root;
}

}  // namespace

std::string quote(const std::string& s) {
  std::string q = "'";
  for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

CommandResult run_command(const std::string& command_line, const RunOptions& options) {
  const fs::path base = test_tmp_root() / unique_name("capture");
  const fs::path out = base.string() + ".out", err = base.string() + ".err";
  // The command runs in a subshell so that its own redirections and pipes stay its own.
  std::string cmd = options.no_display ? "unset DISPLAY WAYLAND_DISPLAY; " : "";
  cmd += "( " + command_line + " ) >" + quote(out.string()) + " 2>" +
         (options.merge_stderr ? std::string("&1") : quote(err.string())) + " </dev/null";
  const int raw = std::system(cmd.c_str());
  CommandResult r;
  r.status = (raw != -1 && WIFEXITED(raw)) ? WEXITSTATUS(raw) : -1;
  if (options.merge_stderr) {
    r.err = slurp(out);
  } else {
    r.out = slurp(out);
    r.err = slurp(err);
  }
  std::error_code ec;
  fs::remove(out, ec);
  fs::remove(err, ec);
  return r;
}

CommandResult run_tool(const std::string& executable, const std::string& args, const RunOptions& options) {
  return run_command(quote(executable) + " " + args, options);
}

TempDir::TempDir(const std::string& prefix) : path_(test_tmp_root() / unique_name(prefix)) {
  std::error_code ec;
  fs::remove_all(path_, ec);  // a leftover of a killed process with a recycled pid
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  if (path_.empty()) return;
  std::error_code ec;
  fs::remove_all(path_, ec);
}

TempDir::TempDir(TempDir&& other) noexcept : path_(std::move(other.path_)) { other.path_.clear(); }

const fs::path& process_temp_dir(const std::string& prefix) {
  static const TempDir dir(prefix);
  return dir.path();
}

}  // namespace terralod::test
