#include "mvkp/recognize/target_db.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/model/model.h"

namespace mvkp {

TrainOptions DbTrainDefaults() { return RecognitionTrainDefaults(); }

TargetRecord MakeTargetRecord(TargetInfo info, std::vector<std::uint8_t> image, const cv::Mat& gray,
                              const TrainOptions& train, const std::string& name) {
  TrainOptions t = train;
  t.progress = nullptr;
  Model model;
  try {
    model = Train(gray, t);
  } catch (const Error& e) {
    if (e.code() == ErrorCode::kNoTexture) throw Error(e.code(), name + ": " + e.what());
    throw;
  }
  TargetRecord r;
  info.width = gray.cols;
  info.height = gray.rows;
  r.info = std::move(info);
  r.image = std::move(image);
  r.model = SerializeModel(model);
  r.encodings.push_back({kWordsEncoding, Recognizer(RecognizerOptions::Words()).Encode(model)});
  return r;
}

std::size_t LoadTargets(const TargetStore& store, Recognizer& rec, const std::string& db,
                        const std::function<void(const TargetInfo&, int, int)>& each,
                        std::vector<SkippedTarget>* skipped) {
  std::set<std::string> done;
  if (rec.options().search == RecognizerSearch::kWords) {
    for (const auto& [info, data] : store.LoadEncodings(kWordsEncoding)) {
      try {
        rec.AddEncoded(info.id, data.data(), data.size());
      } catch (const Error& e) {
        if (e.code() != ErrorCode::kBadModel) throw;
        continue;  // made with another vocabulary or settings, or damaged: encode the model below
      }
      each(info, info.width, info.height);
      done.insert(info.id);
    }
  }
  const std::size_t from_encodings = done.size();
  for (const TargetInfo& info : store.List()) {
    if (done.count(info.id)) continue;
    Model model;
    try {
      const TargetRecord t = store.Get(info.id, /*with_image=*/false);
      model = DeserializeModel(t.model.data(), t.model.size(), db + ": target '" + info.id + "'");
      rec.Add(info.id, model);
    } catch (const Error& e) {
      if (!skipped || e.code() == ErrorCode::kIo) throw;
      skipped->push_back({info.id, e.what()});
      continue;
    }
    each(info, model.object_width, model.object_height);  // its errors are the caller's
  }
  return from_encodings;
}

std::vector<DuplicateOf> FindDuplicates(const Recognizer& rec, const cv::Mat& gray) {
  std::vector<DuplicateOf> out;
  if (rec.size() == 0) return out;
  // Seen as a camera would see the picture filling its frame: database
  // targets are trained at 320 px (DbTrainDefaults) for paintings a quarter
  // to a half of a 640 px frame, so a 1280 px photo of one, searched at its
  // own size, shows it 4x larger than any trained view and is not found
  // (measured: exact copies of 1280 px paintings went unnoticed).
  constexpr int kSide = 480;
  cv::Mat view = gray;
  if (std::max(gray.cols, gray.rows) > kSide) {
    const double s = double(kSide) / std::max(gray.cols, gray.rows);
    cv::resize(gray, view, cv::Size(std::max(1, int(std::lround(gray.cols * s))), std::max(1, int(std::lround(gray.rows * s)))),
               0, 0, cv::INTER_AREA);
  }
  for (const Recognition& f : rec.Recognize(view).found) out.push_back({f.id, f.inliers});
  return out;
}

std::string DescribeDuplicates(const std::vector<DuplicateOf>& found) {
  std::string s = "looks like";
  for (std::size_t i = 0; i < found.size(); ++i)
    s += (i ? ", '" : " '") + found[i].id + "' (" + std::to_string(found[i].inliers) + " inliers)";
  return s;
}

}  // namespace mvkp
