// The mvkp Python module (_mvkp; the package mvkp re-exports it).
#include <opencv2/core/utils/logger.hpp>

#include "common.h"

PYBIND11_MODULE(_mvkp, m) {
  namespace b = mvkp::py_bindings;
  m.doc() = "mvkp: fast planar image matching (Multiple View Kernel Projection) from Python.";
  m.attr("__version__") = MVKP_VERSION;
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  b::RegisterErrors(m);
  b::BindOptions(m);
  b::BindCore(m);
  b::BindRecognize(m);
  b::BindIndex(m);
#ifdef MVKP_PY_AERIAL
  b::BindAerial(m);
  m.attr("HAS_AERIAL") = true;
#else
  m.attr("HAS_AERIAL") = false;
#endif
}
