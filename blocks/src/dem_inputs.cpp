// Several DEM files, or a folder of them, as one raster (see DemInputs in dem_reader.hpp).
#include <gdal_priv.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "gdal_support.hpp"
#include "terralod/blocks/dem_reader.hpp"

namespace terralod::blocks {
namespace {

namespace fs = std::filesystem;

bool is_raster_name(const fs::path& p) {
  // Not .vrt: a folder of tiles often holds a VRT over them too, which would count them twice
  // (a VRT is given as an --input of its own).
  static const std::set<std::string> kExtensions = {".tif", ".tiff", ".hgt", ".asc",
                                                    ".img", ".dem",  ".bil", ".flt"};
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return kExtensions.count(ext) != 0;
}

}  // namespace

DemInputs::DemInputs(const std::vector<std::string>& inputs) {
  if (inputs.empty()) throw DemError("--input", "no input given");
  std::vector<std::string> files;
  std::string folder;
  for (const std::string& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      std::vector<std::string> found;
      for (const auto& e : fs::directory_iterator(in, ec))
        if (e.is_regular_file() && is_raster_name(e.path())) found.push_back(e.path().string());
      if (ec) throw DemError(in, "cannot list the folder: " + ec.message());
      if (found.empty())
        throw DemError(in, "the folder holds no elevation file (.tif .tiff .hgt .asc .img .dem .bil .flt)");
      std::sort(found.begin(), found.end());
      files.insert(files.end(), found.begin(), found.end());
      folder = in;
    } else {
      files.push_back(in);
    }
  }
  files_ = files.size();
  if (files.size() == 1 && folder.empty()) {
    path_ = description_ = files[0];
    return;
  }
  for (const std::string& f : files)
    if (!fs::exists(f)) throw DemError(f, "no such file");
  static std::atomic<int> serial{0};
  path_ = "/vsimem/terralod_inputs_" + std::to_string(::getpid()) + "_" + std::to_string(serial++) + ".vrt";
  if (const std::string why = detail::build_vrt(path_, files); !why.empty())
    throw DemError(folder.empty() ? files[0] : folder, "cannot mosaic the " + std::to_string(files.size()) +
                                                           " inputs into one raster (" + why + ")");
  owned_ = true;
  description_ = "mosaic of " + std::to_string(files.size()) + " files: ";
  for (std::size_t i = 0; i < files.size() && i < 4; ++i)
    description_ += (i ? ", " : "") + fs::path(files[i]).filename().string();
  if (files.size() > 4) description_ += ", ...";
  if (!folder.empty()) description_ += " (in " + folder + ")";
}

DemInputs::~DemInputs() {
  if (owned_) VSIUnlink(path_.c_str());
}

}  // namespace terralod::blocks
