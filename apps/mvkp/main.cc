// mvkp: train planar targets from one image and find them in frames.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>

#include "commands.h"
#include "mvkp/core/error.h"

namespace mvkp::cli {
namespace {
std::vector<std::string> g_argv;
}  // namespace
const std::vector<std::string>& CliArgv() { return g_argv; }
}  // namespace mvkp::cli

int main(int argc, char** argv) {
  mvkp::cli::g_argv.assign(argv, argv + argc);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  CLI::App app{"mvkp - fast planar image matching (Multiple View Kernel Projection)"};
  app.require_subcommand(1);
  cv::setNumThreads(1);
  int threads = 1;
  app.add_option("--threads", threads, "OpenCV worker threads (timings are single-thread by default)")
      ->capture_default_str()
      ->check(CLI::Range(1, 256))
      ->each([](const std::string& v) { cv::setNumThreads(std::stoi(v)); });
  int code = 0;
#ifdef MVKP_VIDEO_HELPER
  // mvkp-video: the `video` subcommand alone, linked with OpenCV's videoio.
  // `mvkp video ...` execs it (video_forward.cc) so that the main binary does
  // not load videoio's ~100 shared libraries (FFmpeg, GStreamer, ...), which
  // cost every other command ~17 MB of resident memory and start-up time.
  mvkp::cli::RegisterVideo(app, &code);
#else
  mvkp::cli::RegisterTrain(app, &code);
  mvkp::cli::RegisterMatch(app, &code);
  mvkp::cli::RegisterPair(app, &code);
  mvkp::cli::RegisterSynth(app, &code);
  mvkp::cli::RegisterBench(app, &code);
  mvkp::cli::RegisterEval(app, &code);
  mvkp::cli::RegisterKnn(app, &code);
  mvkp::cli::RegisterQuality(app, &code);
  mvkp::cli::RegisterDb(app, &code);
  mvkp::cli::RegisterRecognize(app, &code);
  mvkp::cli::RegisterVocab(app, &code);
  mvkp::cli::RegisterServe(app, &code);
  mvkp::cli::RegisterVideo(app, &code);
  mvkp::cli::RegisterSynthCity(app, &code);
  mvkp::cli::RegisterSegment(app, &code);
  mvkp::cli::RegisterRegister(app, &code);
  mvkp::cli::RegisterOrthoModels(app, &code);
#endif
  // CLI11 reports "A subcommand is required" for a misspelt one; name it instead.
  if (argc > 1 && argv[1][0] != '-') {
    bool known = false;
    for (const auto* sub : app.get_subcommands([](const CLI::App*) { return true; })) known |= sub->get_name() == argv[1];
    if (!known) {
      std::fprintf(stderr, "mvkp: unknown command '%s' (see 'mvkp --help')\n", argv[1]);
      return 2;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const mvkp::Error& e) {
    std::fprintf(stderr, "mvkp: error: %s\n", e.what());
    return 1;
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "mvkp: OpenCV error: %s\n", e.err.c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mvkp: error: %s\n", e.what());
    return 1;
  }
  return code;
}
