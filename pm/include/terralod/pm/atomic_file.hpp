// write_file_atomically: a file is either its old content or its whole new content, never a
// part, even when the process is killed while writing (what every writer here needs for resume).
// rename_into_place: the last step of the same, for writers that produce the temporary file
// themselves (GDAL, OpenImageIO, a stream).
//
// Usage:
//   terralod::pm::write_file_atomically("out/12/2425/2958.terrain", bytes);
//   image->write(path + ".tmp");  terralod::pm::rename_into_place(path + ".tmp", path);
//
// Contract: writes the bytes to path + ".tmp", flushes and fsyncs it, and renames it onto
// `path` (atomic on POSIX file systems). The folder must exist. On failure the temporary is
// removed and std::runtime_error says "<path>: <what failed>: <system error>".
// rename_into_place(tmp, path): renames the finished file `tmp` onto `path` (same folder, so
// the same file system); on failure removes `tmp` and throws std::runtime_error
// "<path>: cannot rename <tmp> onto it: <system error>".
// FileRemover: removes its file when it goes out of scope (errors ignored) unless keep() was
// called: the temporary of a writer that fails half-way, or a spool file, is never left behind.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>

namespace terralod::pm {

void write_file_atomically(const std::string& path, std::span<const std::uint8_t> bytes);
void rename_into_place(const std::string& tmp, const std::string& path);
class FileRemover {
 public:
  explicit FileRemover(std::string path) : path_(std::move(path)) {}
  ~FileRemover();
  FileRemover(const FileRemover&) = delete;
  FileRemover& operator=(const FileRemover&) = delete;
  /// The file stays (it was renamed into place, or is the result).
  void keep() { path_.clear(); }

 private:
  std::string path_;
};

inline void write_file_atomically(const std::string& path, std::string_view bytes) {
  write_file_atomically(
      path, std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
}

}  // namespace terralod::pm
