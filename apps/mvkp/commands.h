// The mvkp command-line tool: one Register*/Run* pair per subcommand.
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

namespace mvkp::cli {

// Each Register* adds its subcommand to `app` and arranges for it to run.
// The run callback sets *exit_code.
void RegisterTrain(CLI::App& app, int* exit_code);
void RegisterMatch(CLI::App& app, int* exit_code);
void RegisterPair(CLI::App& app, int* exit_code);
void RegisterSynth(CLI::App& app, int* exit_code);
void RegisterBench(CLI::App& app, int* exit_code);
void RegisterEval(CLI::App& app, int* exit_code);
void RegisterEvalOxford(CLI::App* eval, int* exit_code);  // `eval oxford`, a subcommand of eval
void RegisterEvalSweep(CLI::App* eval, int* exit_code);   // `eval sweep`: the envelope benchmark
void RegisterKnn(CLI::App& app, int* exit_code);
void RegisterQuality(CLI::App& app, int* exit_code);
void RegisterDb(CLI::App& app, int* exit_code);
void RegisterVideo(CLI::App& app, int* exit_code);
void RegisterSynthCity(CLI::App& app, int* exit_code);
void RegisterSynthOblique(CLI::App& app, int* exit_code);
void RegisterRegisterView(CLI::App& app, int* exit_code);
void RegisterRegisterAll(CLI::App& app, int* exit_code);
void RegisterSegment(CLI::App& app, int* exit_code);
void RegisterRegister(CLI::App& app, int* exit_code);
void RegisterOrthoModels(CLI::App& app, int* exit_code);
void RegisterRecognize(CLI::App& app, int* exit_code);
void RegisterVocab(CLI::App& app, int* exit_code);
void RegisterServe(CLI::App& app, int* exit_code);

// Stage 1 of aerial registration with mvkp register's defaults: what
// `mvkp register DEPTH NADIR --json [--res RES_M]` prints (cmd_aerial.cc).
nlohmann::json RegisterNadir(const std::string& depth, const std::string& nadir, double res_m = 0);

// The process's command line as main() received it (video_forward.cc passes
// it on to the mvkp-video helper).
const std::vector<std::string>& CliArgv();

}  // namespace mvkp::cli
