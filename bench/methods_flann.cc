// OpenCV FLANN baseline: randomised KD-trees (cv::flann::Index).
#include <opencv2/flann.hpp>

#include "methods.h"

namespace mvkp::bench {
namespace {

class FlannKdTree : public Method {
 public:
  static constexpr int kTrees = 4, kChecks = 64;
  void Build(const float* data, std::size_t n, int dim) override {
    index_.reset();
    // cv::flann::Index keeps a reference to the features: give it its own copy.
    features_ = cv::Mat(int(n), dim, CV_32F, const_cast<float*>(data)).clone();
    index_ = std::make_unique<cv::flann::Index>(features_, cv::flann::KDTreeIndexParams(kTrees), cvflann::FLANN_DIST_L2);
  }
  void SearchOne(const float* q, int k, std::int64_t* ids, float* dists) override {
    Search(q, 1, k, ids, dists);
  }
  bool has_batch() const override { return true; }
  void SearchBatch(const float* q, std::size_t nq, int k, std::int64_t* ids, float* dists) override {
    Search(q, nq, k, ids, dists);
  }

 private:
  void Search(const float* q, std::size_t nq, int k, std::int64_t* ids, float* dists) {
    const cv::Mat query(int(nq), features_.cols, CV_32F, const_cast<float*>(q));
    index_->knnSearch(query, indices_, distances_, k, cv::flann::SearchParams(kChecks));
    for (std::size_t i = 0; i < nq; ++i)
      for (int j = 0; j < k; ++j) {
        const int id = indices_.at<int>(int(i), j);
        ids[i * k + j] = id;
        dists[i * k + j] = id < 0 ? -1.f : distances_.at<float>(int(i), j);
      }
  }

  cv::Mat features_, indices_, distances_;
  std::unique_ptr<cv::flann::Index> index_;
};

}  // namespace

void AddFlannMethods(std::vector<MethodInfo>& out) {
  out.push_back({"flann-kdtree",
                 "cv::flann KDTreeIndexParams(" + std::to_string(FlannKdTree::kTrees) + ") checks=" +
                     std::to_string(FlannKdTree::kChecks),
                 "", [] { return std::make_unique<FlannKdTree>(); }});
}

}  // namespace mvkp::bench
