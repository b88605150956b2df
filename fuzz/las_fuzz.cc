// The LAS reader (mvkp/geo/raster.h): RasteriseLasBytes on arbitrary bytes
// returns a depth raster within the grid limit or throws mvkp::Error.
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "mvkp/core/error.h"
#include "mvkp/geo/raster.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  mvkp::geo::LasRasterOptions o;
  o.res_m = 1.0;
  o.max_side = 256;  // a small grid keeps runs fast; the check against it is what is tested
  o.drop_noise = size % 2;
  o.fill_max_gap_m = size % 3 ? 3.0 : 0.0;
  try {
    const mvkp::geo::DepthRaster d = mvkp::geo::RasteriseLasBytes("fuzz.las", data, size, o);
    if (d.z.empty() || d.z.cols > o.max_side || d.z.rows > o.max_side || !d.has_geo) std::abort();
    for (float z : d.z)
      if (std::isinf(z)) std::abort();  // NaN (no data) is allowed, infinite heights are not
  } catch (const mvkp::Error&) {
  }
  return 0;
}
