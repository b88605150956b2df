// `mvkp video` in the main binary: hands the whole command line to the
// mvkp-video helper (main.cc built with MVKP_VIDEO_HELPER and cmd_video.cc).
// Only that helper links OpenCV's videoio, whose dependencies (FFmpeg,
// GStreamer, librsvg, ...) would otherwise be loaded by every command.
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "commands.h"

#ifndef MVKP_HELPER_REL
#define MVKP_HELPER_REL "../libexec/mvkp"  // from the binary's folder to the installed helpers
#endif

namespace mvkp::cli {
namespace {

namespace fs = std::filesystem;

// The helper beside this binary (build tree) or in the installed helper folder.
std::vector<fs::path> HelperCandidates() {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const fs::path dir = self.parent_path();
  return {dir / "mvkp-video", (dir / MVKP_HELPER_REL / "mvkp-video").lexically_normal()};
}

}  // namespace

void RegisterVideo(CLI::App& app, int* code) {
  auto* c = app.add_subcommand("video", "Recognise database targets in a video or camera, with temporal focus");
  // Every argument, --help included, goes to the helper, which parses it.
  c->set_help_flag();
  c->prefix_command();
  c->callback([code] {
    const std::vector<std::string>& argv_in = CliArgv();
    std::vector<char*> argv;
    for (const auto& s : argv_in) argv.push_back(const_cast<char*>(s.c_str()));
    argv.push_back(nullptr);
    std::string tried;
    for (const fs::path& p : HelperCandidates()) {
      std::error_code ec;
      if (!fs::is_regular_file(p, ec)) {
        tried += (tried.empty() ? "" : ", ") + p.string();
        continue;
      }
      std::fflush(nullptr);
      execv(p.c_str(), argv.data());
      std::fprintf(stderr, "mvkp video: cannot run %s: %s\n", p.c_str(), std::strerror(errno));
      *code = 1;
      return;
    }
    std::fprintf(stderr, "mvkp video: needs its helper mvkp-video, not found (looked at %s)\n",
                 tried.empty() ? "nothing: /proc/self/exe unreadable" : tried.c_str());
    *code = 1;
  });
}

}  // namespace mvkp::cli
