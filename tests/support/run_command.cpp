// Test support: runs command lines capturing their streams and exit status, and per-process
// scratch folders (see run_command.hpp).
#include "run_command.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
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

fs::path shared_file(const std::string& name, const std::function<void(const fs::path&)>& build) {
  const fs::path exe = fs::read_symlink("/proc/self/exe");
  const std::string stem = "shared-" + exe.filename().string() + "-";
  const std::string key = std::to_string(fs::file_size(exe)) + "-" +
                          std::to_string(fs::last_write_time(exe).time_since_epoch().count());
  const fs::path dir = test_tmp_root() / (stem + key);
  const fs::path target = dir / name;
  if (fs::exists(target)) return target;
  fs::create_directories(dir);
  // One builder at a time: ctest starts the tests of one executable side by side, and each
  // would otherwise build the same file at once, on the same 2 cores (three runtime tests over
  // one database, ctest -j2 under ASan: 36.6 s, 24.3 s with the lock); the others wait for it
  // and reuse its file. The lock goes with its descriptor, also when a builder is killed.
  const fs::path lock_path = dir / (name + ".lock");
  const int lock = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock < 0) throw std::system_error(errno, std::generic_category(), "cannot open " + lock_path.string());
  struct Unlock {
    int fd;
    ~Unlock() { ::close(fd); }
  } unlock{lock};
  while (::flock(lock, LOCK_EX) != 0)
    if (errno != EINTR)
      throw std::system_error(errno, std::generic_category(), "cannot lock " + lock_path.string());
  if (fs::exists(target)) return target;
  // Folders of this executable's older builds: nothing of theirs is read any more.
  for (const fs::directory_entry& e : fs::directory_iterator(test_tmp_root())) {
    const std::string n = e.path().filename().string();
    std::error_code ec;
    if (n.rfind(stem, 0) == 0 && n != stem + key) fs::remove_all(e.path(), ec);
  }
  const fs::path mine = dir / unique_name("building-" + name);
  try {
    build(mine);
  } catch (...) {
    std::error_code ec;
    fs::remove(mine, ec);
    throw;
  }
  // link() fails when another process placed its (identical) file first; either way the file at
  // `target` is complete, because it only ever appears there whole.
  if (::link(mine.c_str(), target.c_str()) != 0 && errno != EEXIST)
    throw std::system_error(errno, std::generic_category(),
                            "cannot link " + mine.string() + " to " + target.string());
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) fs::remove(mine.string() + suffix, ec);
  return target;
}

const fs::path& process_temp_dir(const std::string& prefix) {
  static const TempDir dir(prefix);
  return dir.path();
}

}  // namespace terralod::test
