// LD_PRELOAD shim for the ASan tests of `make sanitize` (issue 19): lets one
// known read past the end of a heap buffer inside OpenCV finish instead of
// crashing, and leaves every other fault to ASan.
//
// The bug (Debian 12's OpenCV 4.6, not mvkp): cv::findHomography with
// UsacParams and SAMPLING_PROSAC, which mvkp's matcher uses by default, builds
// a PROSAC termination criterion with a minimum termination length of 100 and
// then counts inliers over the first 100 reprojection errors, even when there
// are fewer points: with N < 100 correspondences it reads 4 * (100 - N) bytes
// past OpenCV's own N-float error vector. The value is not used when N < 100
// (the loop that would use it does not run), so results are unaffected, and
// in a normal build the bytes read are other heap memory. valgrind shows it on
// the gcc build ("Invalid read of size 4 ... 0 bytes after a block of size
// 160 alloc'd" under cv::findHomography, 40 points). Later OpenCV versions
// rewrote USAC (4.8) and assert the length against the number of points.
//
// Under ASan the error vector can be the last chunk before unmapped heap, and
// then the read faults (a SEGV "in libopencv_calib3d" under mvkp::FitGeometry,
// in a few of the ~300 tests per run, depending on the heap layout). ASan
// cannot report or suppress it: OpenCV is not instrumented. So this handler,
// for a READ fault whose instruction is in libopencv_calib3d and whose address
// is in ASan's heap, maps a zero page there and resumes; ASan maps its heap
// over it when it grows. Any other fault goes to ASan's handler as before.
// It needs ASAN_OPTIONS=allow_user_segv_handler=1 and does nothing in a
// process without ASan. Drop it with OpenCV >= 4.8.
#include <dlfcn.h>
#include <signal.h>
#include <sys/mman.h>
#include <ucontext.h>

#include <cstdint>
#include <cstring>

namespace {

// ASan's allocator space on x86-64 Linux (kAllocatorSpace, kAllocatorSize).
constexpr std::uintptr_t kAsanHeapBegin = 0x600000000000ULL, kAsanHeapEnd = 0x640000000000ULL;
constexpr std::uintptr_t kPage = 4096;

struct sigaction g_asan_handler;

bool InOpencvCalib3d(std::uintptr_t pc) {
  Dl_info info;
  return dladdr(reinterpret_cast<void*>(pc), &info) != 0 && info.dli_fname != nullptr &&
         std::strstr(info.dli_fname, "libopencv_calib3d.so") != nullptr;
}

void OnSegv(int sig, siginfo_t* si, void* context) {
  const auto* uc = static_cast<const ucontext_t*>(context);
  const std::uintptr_t pc = static_cast<std::uintptr_t>(uc->uc_mcontext.gregs[REG_RIP]);
  const bool write = (uc->uc_mcontext.gregs[REG_ERR] & 2) != 0;  // page-fault error code: bit 1 = write
  const std::uintptr_t addr = reinterpret_cast<std::uintptr_t>(si->si_addr);
  if (!write && addr >= kAsanHeapBegin && addr < kAsanHeapEnd && InOpencvCalib3d(pc)) {
    void* page = reinterpret_cast<void*>(addr & ~(kPage - 1));
    if (mmap(page, kPage, PROT_READ, MAP_PRIVATE | MAP_ANONYMOUS | MAP_FIXED, -1, 0) != MAP_FAILED) return;
  }
  if (g_asan_handler.sa_flags & SA_SIGINFO) {
    g_asan_handler.sa_sigaction(sig, si, context);
  } else if (g_asan_handler.sa_handler != SIG_DFL && g_asan_handler.sa_handler != SIG_IGN) {
    g_asan_handler.sa_handler(sig);
  } else {
    signal(sig, SIG_DFL);
    raise(sig);
  }
}

// Runs after ASan's initialisation (it runs from the executable's
// preinit_array), so the handler saved here is ASan's.
__attribute__((constructor)) void Install() {
  if (dlsym(RTLD_DEFAULT, "__asan_init") == nullptr) return;
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_sigaction = OnSegv;
  sa.sa_flags = SA_SIGINFO | SA_ONSTACK;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGSEGV, &sa, &g_asan_handler);
}

}  // namespace
