// write_file_atomically and rename_into_place (see atomic_file.hpp).
#include "terralod/pm/atomic_file.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace terralod::pm {

void write_file_atomically(const std::string& path, std::span<const std::uint8_t> bytes) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw std::runtime_error(path + ": cannot write " + tmp + ": " + std::strerror(errno));
  // Report the first failure's errno (a full disk fails the write or flush with ENOSPC; the
  // fsync after it would overwrite that with something less telling).
  int err = 0;
  auto step = [&err](bool done) {
    if (!done && err == 0) err = errno ? errno : EIO;
  };
  step(std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size());
  step(std::fflush(f) == 0);
  step(::fsync(::fileno(f)) == 0);
  step(std::fclose(f) == 0);
  if (err != 0) {
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot write " + tmp + ": " + std::strerror(err));
  }
  rename_into_place(tmp, path);
}

void rename_into_place(const std::string& tmp, const std::string& path) {
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(tmp.c_str());
    throw std::runtime_error(path + ": cannot rename " + tmp + " onto it: " + std::strerror(e));
  }
}

FileRemover::~FileRemover() {
  if (path_.empty()) return;
  std::error_code ec;
  std::filesystem::remove(path_, ec);
}

}  // namespace terralod::pm
