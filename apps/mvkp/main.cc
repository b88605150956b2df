// mvkp: train planar targets from one image and find them in frames.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>

#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/model/model.h"

#ifndef MVKP_VERSION_STRING
#define MVKP_VERSION_STRING "unknown"
#endif

namespace mvkp::cli {
namespace {
std::vector<std::string> g_argv;
}  // namespace
const std::vector<std::string>& CliArgv() { return g_argv; }

namespace {
// "mvkp db add": the subcommands the command line selected, for error messages
// ("mvkp SUBCOMMAND: message", the one style every command uses).
std::string CommandPath(const CLI::App& app) {
  std::string path = "mvkp";
  const CLI::App* at = &app;
  for (;;) {
    const auto subs = at->get_subcommands();
    if (subs.empty()) break;
    at = subs.front();
    path += " " + at->get_name();
  }
  return path;
}
}  // namespace
}  // namespace mvkp::cli

int main(int argc, char** argv) {
  mvkp::cli::g_argv.assign(argv, argv + argc);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  CLI::App app{"mvkp - fast planar image matching (Multiple View Kernel Projection)"};
  app.require_subcommand(0, 1);
  app.set_version_flag("--version",
                       std::string("mvkp ") + MVKP_VERSION_STRING + " (model format " +
                           std::to_string(mvkp::kModelFormatVersion) + ", OpenCV " + CV_VERSION + ")",
                       "print the version and exit");
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
  mvkp::cli::RegisterSynthOblique(app, &code);
  mvkp::cli::RegisterRegisterView(app, &code);
  mvkp::cli::RegisterRegisterAll(app, &code);
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
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // Usage errors in the same style as every other error, with where to look.
    const std::string where = mvkp::cli::CommandPath(app);
    std::fprintf(stderr, "%s: %s (see '%s --help')\n", where.c_str(), e.what(), where.c_str());
    return 2;  // usage error
  } catch (const mvkp::Error& e) {
    std::fprintf(stderr, "%s: %s\n", mvkp::cli::CommandPath(app).c_str(), e.what());
    return 1;
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "%s: OpenCV error: %s\n", mvkp::cli::CommandPath(app).c_str(), e.err.c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", mvkp::cli::CommandPath(app).c_str(), e.what());
    return 1;
  }
  // A bare `mvkp`: what it can do (stdout), and a usage error (stderr, exit 2).
  if (app.get_subcommands().empty()) {
    std::fputs(app.help().c_str(), stdout);
    std::fputs("mvkp: a command is required (see the list above, or 'mvkp COMMAND --help')\n", stderr);
    return 2;
  }
  return code;
}
