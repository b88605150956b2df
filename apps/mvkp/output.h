// Shared CLI helpers: option groups, JSON encoding and drawing.
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "mvkp/match/matcher.h"
#include "mvkp/quality/quality.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/serve/encode.h"
#include "mvkp/train/trainer.h"

namespace mvkp::cli {

// Adds --views, --locations, --clusters, --kernels, --seed, ... to a command.
void AddTrainOptions(CLI::App* cmd, TrainOptions* o);
// Adds --ratio, --dynamic-goal, --affine, --max-points, ... to a command.
void AddMatchOptions(CLI::App* cmd, MatchOptions* o, bool* affine);

nlohmann::json HomographyJson(const MatchResult& r);  // 3x3 array or null
nlohmann::json TimingJson(const MatchTiming& t);

// Train() on an image loaded from `path`; errors name the file.
Model TrainNamed(const std::string& path, const cv::Mat& gray, const TrainOptions& options,
                 TrainReport* report = nullptr);

// Frame with the outline, inliers (green) and other matches (red).
cv::Mat DrawMatch(const cv::Mat& frame_gray_or_bgr, const MatchResult& r);
// Object and frame side by side, inlier lines, outline.
cv::Mat DrawPair(const cv::Mat& object, const cv::Mat& frame, const MatchResult& r);

// "out.png" with index 3 of several -> "out-3.png"; unchanged when count == 1.
std::string IndexedPath(const std::string& path, int index, int count);

// "1 target", "3 targets": a count with its noun in the right number
// (`plural` when it is not the noun + "s").
std::string Count(std::size_t n, const std::string& noun, const std::string& plural = "");

// Median of a sample (0 when empty).
double Median(std::vector<double> v);

// Progress line on stderr when it is a terminal.
void Progress(const std::string& what, int done, int total);

// The JSON answers shared with the guide service (mvkp/serve/encode.h).
using serve::DatabaseQualityJson;
using serve::QualityJson;
using serve::RecognitionJson;

}  // namespace mvkp::cli
