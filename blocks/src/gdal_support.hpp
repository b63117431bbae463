// Private to terralod::blocks: GDAL registered once per process, whoever asks first.
#pragma once

#include <gdal_priv.h>

#include <mutex>

namespace terralod::blocks::detail {

inline void register_gdal() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

}  // namespace terralod::blocks::detail
