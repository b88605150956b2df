// A target database (mvkp/db) as a recogniser sees it: making records (`mvkp
// db add / import`, the guide service's admin API) and loading a database into
// a Recognizer (`mvkp recognize`, `mvkp video`, the guide service).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/db/target_store.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/train/trainer.h"

namespace mvkp {

// The kind under which records store Recognizer::Encode bytes.
constexpr const char* kWordsEncoding = "words";

// Recognition targets are trained smaller and over a wider scale range than
// `mvkp train`'s defaults: in a gallery photo a painting often spans a quarter
// to a half of the frame, below the default smallest view scale (0.4) of a
// 640 px target. Measured on the gallery scenes of docs/gallery.md: recall
// 28.6 % with the train defaults, 89 % with these.
TrainOptions DbTrainDefaults();

// Trains a target from its image (`gray`, decoded from `image`) and packs it
// with its model and its word encoding (so the word search need not decode
// thousands of models). `name` names the image in errors.
TargetRecord MakeTargetRecord(TargetInfo info, std::vector<std::uint8_t> image, const cv::Mat& gray,
                              const TrainOptions& train, const std::string& name);

// A target LoadTargets left out, and why.
struct SkippedTarget {
  std::string id;
  std::string error;
};

// Adds every target of `store` to `rec` and calls `each(info, width, height)`
// (the target's size in its model's pixels) for it. The word search takes the
// stored encodings that fit its vocabulary and settings and decodes only the
// other targets' models (older databases, other settings); the exact search
// decodes every model. Returns the number of targets that came from
// encodings. Errors name `db` and the target.
//
// A target whose model cannot be read (damaged row): with `skipped` it is left
// out and listed there, so one bad row does not take the others down; without
// it, the Error is thrown.
std::size_t LoadTargets(const TargetStore& store, Recognizer& rec, const std::string& db,
                        const std::function<void(const TargetInfo&, int, int)>& each,
                        std::vector<SkippedTarget>* skipped = nullptr);

// An existing target that a new image shows, and how strongly.
struct DuplicateOf {
  std::string id;
  int inliers = 0;
};

// The targets of `rec` that `gray` (a new target's image) shows, seen as a
// frame: the same picture, a crop of it, a brighter, smaller or re-encoded
// copy. Two copies of one picture under two ids take each other's votes and
// neither is found any more, so `db add`, `db import` and the admin API refuse
// such an image unless told to allow it. Most inliers first; empty when the
// image shows none of them (the recogniser's own acceptance rules: it reports
// no target on frames that show none, measured 0 of 300 on the gallery's).
std::vector<DuplicateOf> FindDuplicates(const Recognizer& rec, const cv::Mat& gray);

// "looks like 'a' (57 inliers), 'b' (12 inliers)": for messages.
std::string DescribeDuplicates(const std::vector<DuplicateOf>& found);

}  // namespace mvkp
