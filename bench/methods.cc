#include "methods.h"

#include <dlfcn.h>

#include <opencv2/core.hpp>

#if MVKP_BENCH_HAVE_FAISS
#include <omp.h>
#endif

namespace mvkp::bench {

std::vector<MethodInfo> AllMethods() {
  std::vector<MethodInfo> out;
  AddMvkpMethods(out);
#if MVKP_BENCH_HAVE_FAISS
  AddFaissMethods(out);
#endif
#if MVKP_BENCH_HAVE_HNSWLIB
  AddHnswlibMethods(out);
#endif
#if MVKP_BENCH_HAVE_FLANN
  AddFlannMethods(out);
#endif
  return out;
}

void SingleThreaded() {
  cv::setNumThreads(1);
#if MVKP_BENCH_HAVE_FAISS
  omp_set_num_threads(1);
#endif
  // When the BLAS behind FAISS is OpenBLAS (Debian's libblas.so.3 alternative
  // may point to it), its own thread pool ignores OpenMP's setting.
  using SetThreads = void (*)(int);
  if (auto f = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) f(1);
}

#if !MVKP_BENCH_HAVE_FAISS
std::string FaissEnvironment() { return ""; }
#endif
#if !MVKP_BENCH_HAVE_HNSWLIB
std::string HnswlibEnvironment() { return ""; }
#endif

}  // namespace mvkp::bench
