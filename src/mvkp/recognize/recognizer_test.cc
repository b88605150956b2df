#include "mvkp/recognize/recognizer.h"

#include <map>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/synth/synth.h"
#include "mvkp/train/trainer.h"

#include "test_samples.h"

namespace mvkp {
namespace {

using mvkp::testing::Sample;

// Four targets trained once (default training options) for the whole suite;
// fruits.jpg and baboon.jpg are not among them.
class RecognizerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    for (const char* name : {"starry_night", "astronaut", "building", "coffee"}) {
      (*images_)[name] = PrepareTarget(Sample(std::string(name) + ".jpg"), 320);
      (*models_)[name] = Train((*images_)[name], {});
    }
  }
  static Recognizer MakeRecognizer(const RecognizerOptions& o = {}) {
    Recognizer rec(o);
    for (const auto& [id, m] : *models_) rec.Add(id, m);
    return rec;
  }
  static const Recognition* Find(const RecognitionResult& r, const std::string& id) {
    for (const auto& f : r.found)
      if (f.id == id) return &f;
    return nullptr;
  }
  // Over 10 synthetic scenes of target `id`: frames where it is found first
  // within max_error px, and other ids reported.
  struct Tally {
    int ok = 0, wrong = 0;
  };
  static Tally RecogniseScenes(const Recognizer& rec, const std::string& id, double max_error) {
    const cv::Mat& img = images_->at(id);
    Tally t;
    for (int i = 0; i < 10; ++i) {
      const SceneView v = MakeSceneView(img, SceneOptions{}, 2000 + i);
      const RecognitionResult r = rec.Recognize(v.image);
      const Recognition* f = Find(r, id);
      if (!r.found.empty() && r.found[0].id == id && f && MeanCornerError(f->homography, v.H, img.size()) < max_error)
        ++t.ok;
      for (const auto& x : r.found) t.wrong += x.id != id;
    }
    return t;
  }
  // Two runs on one frame give the same targets, inliers and homographies.
  static void ExpectDeterministic(const Recognizer& rec) {
    const SceneView v = MakeSceneView(images_->at("coffee"), SceneOptions{}, 5000);
    const RecognitionResult a = rec.Recognize(v.image), b = rec.Recognize(v.image);
    ASSERT_EQ(a.found.size(), b.found.size());
    ASSERT_FALSE(a.found.empty());
    EXPECT_EQ(a.found[0].inliers, b.found[0].inliers);
    EXPECT_EQ(cv::norm(cv::Mat(a.found[0].homography), cv::Mat(b.found[0].homography), cv::NORM_INF), 0.0);
  }
  static inline auto* images_ = new std::map<std::string, cv::Mat>;
  static inline auto* models_ = new std::map<std::string, Model>;
};

TEST_F(RecognizerTest, RecognisesEachTargetInSyntheticScenes) {
  const Recognizer rec = MakeRecognizer();
  ASSERT_EQ(rec.size(), 4u);
  for (const auto& [id, img] : *images_) {
    const Tally t = RecogniseScenes(rec, id, 5.0);
    EXPECT_GE(t.ok, 8) << id;
    EXPECT_EQ(t.wrong, 0) << id;
  }
}

TEST_F(RecognizerTest, FindsTwoTargetsInOneFrame) {
  const Recognizer rec = MakeRecognizer();
  cv::Mat canvas(480, 960, CV_8UC1);
  cv::randn(canvas, 128, 10);
  const cv::Mat& a = images_->at("starry_night");
  const cv::Mat& b = images_->at("astronaut");
  const cv::Matx33d Ha(0.9, 0, 40, 0, 0.9, 60, 0, 0, 1);
  const cv::Matx33d Hb(1.1, 0, 520, 0, 1.1, 50, 0, 0, 1);
  cv::warpPerspective(a, canvas, cv::Mat(Ha), canvas.size(), cv::INTER_LINEAR, cv::BORDER_TRANSPARENT);
  cv::warpPerspective(b, canvas, cv::Mat(Hb), canvas.size(), cv::INTER_LINEAR, cv::BORDER_TRANSPARENT);
  const RecognitionResult r = rec.Recognize(canvas);
  ASSERT_EQ(r.found.size(), 2u) << "candidates " << r.candidates << ", matches " << r.matches;
  const Recognition* fa = Find(r, "starry_night");
  const Recognition* fb = Find(r, "astronaut");
  ASSERT_TRUE(fa && fb);
  EXPECT_LT(MeanCornerError(fa->homography, Ha, a.size()), 5.0);
  EXPECT_LT(MeanCornerError(fb->homography, Hb, b.size()), 5.0);
  EXPECT_GE(fa->inliers, 12);
  EXPECT_GE(fb->inliers, 12);
  EXPECT_GE(r.found[0].inliers, r.found[1].inliers);
  for (const auto& f : r.found) EXPECT_TRUE(f.score > 0 && f.score <= 1);
}

// Issue 20: the targets verified per frame are the max_candidates with most
// votes; a caller that knows some are in view makes room for others.
TEST_F(RecognizerTest, MoreCandidatesMakeRoomForMoreTargetsInOneFrame) {
  RecognizerOptions o;
  o.max_candidates = 2;
  const Recognizer rec = MakeRecognizer(o);
  cv::Mat canvas(480, 1280, CV_8UC1);
  cv::randn(canvas, 128, 10);
  const std::vector<std::pair<std::string, cv::Matx33d>> placed = {
      {"starry_night", cv::Matx33d(0.9, 0, 20, 0, 0.9, 60, 0, 0, 1)},
      {"astronaut", cv::Matx33d(1.0, 0, 340, 0, 1.0, 60, 0, 0, 1)},
      {"coffee", cv::Matx33d(0.9, 0, 680, 0, 0.9, 60, 0, 0, 1)},
      {"building", cv::Matx33d(0.9, 0, 980, 0, 0.9, 60, 0, 0, 1)}};
  for (const auto& [id, H] : placed)
    cv::warpPerspective(images_->at(id), canvas, cv::Mat(H), canvas.size(), cv::INTER_LINEAR, cv::BORDER_TRANSPARENT);
  EXPECT_EQ(rec.Recognize(canvas).found.size(), 2u);
  const RecognitionResult r = rec.Recognize(canvas, 4);
  EXPECT_EQ(r.candidates, 4);
  ASSERT_EQ(r.found.size(), 4u);
  for (const auto& [id, H] : placed) {
    const Recognition* f = Find(r, id);
    ASSERT_TRUE(f) << id;
    EXPECT_LT(MeanCornerError(f->homography, H, images_->at(id).size()), 5.0) << id;
  }
  EXPECT_THROW(rec.Recognize(canvas, 0), Error);
}

TEST_F(RecognizerTest, FindsNothingInANonTarget) {
  const Recognizer rec = MakeRecognizer();
  for (const char* other : {"fruits.jpg", "baboon.jpg"}) {
    const RecognitionResult plain = rec.Recognize(Sample(other));
    EXPECT_TRUE(plain.found.empty()) << other << ": " << plain.found[0].id << " " << plain.found[0].inliers;
    const cv::Mat target = PrepareTarget(Sample(other), 320);
    for (int i = 0; i < 3; ++i) {
      const RecognitionResult r = rec.Recognize(MakeSceneView(target, SceneOptions{}, 3000 + i).image);
      EXPECT_TRUE(r.found.empty()) << other << " view " << i << ": " << r.found[0].id << " " << r.found[0].inliers;
    }
  }
}

TEST_F(RecognizerTest, RemovedTargetIsNotFound) {
  Recognizer rec = MakeRecognizer();
  const cv::Mat& img = images_->at("building");
  const SceneView v = MakeSceneView(img, SceneOptions{}, 4000);
  ASSERT_TRUE(Find(rec.Recognize(v.image), "building"));
  EXPECT_TRUE(rec.Remove("building"));
  EXPECT_FALSE(rec.Remove("building"));
  EXPECT_EQ(rec.size(), 3u);
  const RecognitionResult r = rec.Recognize(v.image);
  EXPECT_TRUE(r.found.empty()) << r.found[0].id;
  // Re-adding works, and the others are still found.
  rec.Add("building", models_->at("building"));
  EXPECT_TRUE(Find(rec.Recognize(v.image), "building"));
  const SceneView c = MakeSceneView(images_->at("coffee"), SceneOptions{}, 4001);
  EXPECT_TRUE(Find(rec.Recognize(c.image), "coffee"));
}

TEST_F(RecognizerTest, IsDeterministic) { ExpectDeterministic(MakeRecognizer()); }

// The probed search (an inverted file over the vocabulary) finds what the
// exhaustive one finds on these scenes, rejects the same non-targets, and
// keeps working through removals and re-additions (each target's word
// assignment is cached, the lists rebuilt).
TEST_F(RecognizerTest, ProbedSearchRecognisesAsTheExhaustiveOneDoes) {
  RecognizerOptions o;
  o.probe_words = 4;
  Recognizer rec = MakeRecognizer(o);
  for (const auto& [id, img] : *images_) {
    const Tally t = RecogniseScenes(rec, id, 5.0);
    EXPECT_GE(t.ok, 8) << id;
    EXPECT_EQ(t.wrong, 0) << id;
  }
  for (const char* other : {"fruits.jpg", "baboon.jpg"}) {
    const RecognitionResult r = rec.Recognize(Sample(other));
    EXPECT_TRUE(r.found.empty()) << other << ": " << r.found[0].id;
  }
  ExpectDeterministic(rec);
  const SceneView v = MakeSceneView(images_->at("building"), SceneOptions{}, 4000);
  EXPECT_TRUE(rec.Remove("building"));
  const RecognitionResult gone = rec.Recognize(v.image);
  EXPECT_TRUE(gone.found.empty()) << gone.found[0].id;
  rec.Add("building", models_->at("building"));
  EXPECT_TRUE(Find(rec.Recognize(v.image), "building"));
  // Probing every word is the exhaustive search over the same centres. (With
  // a plain ratio test: both indexes decide the test exactly but may report a
  // passing match's second distance larger than it is, each in its own way,
  // and the dynamic ratio ranks by those distances.)
  o.probe_words = DefaultVocabulary().size();
  o.match.dynamic_goal = 0;
  RecognizerOptions e;
  e.probe_words = 0;
  e.match.dynamic_goal = 0;
  const Recognizer all = MakeRecognizer(o), exact = MakeRecognizer(e);
  const RecognitionResult a = all.Recognize(v.image), b = exact.Recognize(v.image);
  ASSERT_EQ(a.found.size(), b.found.size());
  ASSERT_FALSE(a.found.empty());
  EXPECT_EQ(a.found[0].id, b.found[0].id);
  // The inverted file computes distances as |x|^2 + |q|^2 - 2 x.q, FFVA as
  // (x - q)^2: a match right at the ratio threshold can fall either side.
  EXPECT_NEAR(a.found[0].votes, b.found[0].votes, 2);
  EXPECT_NEAR(a.found[0].inliers, b.found[0].inliers, 2);
}

TEST_F(RecognizerTest, RejectsDuplicatesAndMismatchedFeatures) {
  Recognizer rec = MakeRecognizer();
  EXPECT_THROW(rec.Add("coffee", models_->at("starry_night")), Error);
  EXPECT_THROW(rec.Add("", models_->at("starry_night")), Error);
  Model m = models_->at("coffee");
  m.params.smooth_sigma = 1.5f;
  EXPECT_THROW(rec.Add("coffee-sigma", m), Error);
  m = models_->at("coffee");
  m.params.orientation_radius = 11;
  EXPECT_THROW(rec.Add("coffee-radius", m), Error);
  m = models_->at("coffee");
  m.params.min_strength *= 2;
  EXPECT_THROW(rec.Add("coffee-threshold", m), Error);
  EXPECT_EQ(rec.size(), 4u);
  // The training record may differ.
  m = models_->at("coffee");
  m.params.views = 7;
  EXPECT_NO_THROW(rec.Add("coffee2", m));
  EXPECT_GT(rec.memory_bytes(), 0u);
}

TEST(Recognizer, EmptyAndBadInput) {
  const Recognizer rec;
  EXPECT_TRUE(rec.Recognize(cv::Mat(100, 100, CV_8UC1, cv::Scalar(0))).found.empty());
  EXPECT_THROW(rec.Recognize(cv::Mat(100, 100, CV_8UC3)), Error);
  RecognizerOptions o;
  o.min_inliers = 2;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.max_candidates = 0;
  EXPECT_THROW(Recognizer{o}, Error);
}

TEST_F(RecognizerTest, DynamicRatioCapsEachTargetsMatchesAndStillFindsIt) {
  RecognizerOptions o;
  o.match.dynamic_goal = 30;
  o.match.ratio_min = 0.01f;  // (almost) no match counts regardless of the goal
  o.match.ratio_max = 0.95f;
  const Recognizer rec = MakeRecognizer(o);
  int ok = 0;
  for (const char* id : {"starry_night", "coffee"}) {
    const cv::Mat& img = images_->at(id);
    for (int i = 0; i < 5; ++i) {
      const SceneView v = MakeSceneView(img, SceneOptions{}, 2000 + i);
      const RecognitionResult r = rec.Recognize(v.image);
      for (const auto& f : r.found) EXPECT_LE(f.votes, 30) << id;
      const Recognition* f = Find(r, id);
      ok += f && MeanCornerError(f->homography, v.H, img.size()) < 5.0;
    }
  }
  EXPECT_GE(ok, 8);  // of 10
}

// The word-based search (inverted file + Hamming signatures) on the same targets.
RecognizerOptions WordsOptions() { return RecognizerOptions::Words(); }

TEST_F(RecognizerTest, WordsRecogniseEachTargetInSyntheticScenesWithAFewKilobytesPerTarget) {
  Recognizer rec = MakeRecognizer(WordsOptions());
  rec.ShrinkToFit();
  // The ARCore-like budget of issue 6: at most 8 KB per target.
  EXPECT_LT(rec.memory_bytes() / rec.size(), 8192u);
  int total = 0;
  for (const auto& [id, img] : *images_) {
    const Tally t = RecogniseScenes(rec, id, 10.0);
    // Weaker than kExact's 8 of 10 within 5 px on these views (measured 5-9
    // of 10 within 10 px): the price of ~7 KB per target instead of ~700.
    EXPECT_GE(t.ok, 5) << id;
    EXPECT_EQ(t.wrong, 0) << id;
    total += t.ok;
  }
  EXPECT_GE(total, 26);  // of 40
}

TEST_F(RecognizerTest, WordsFindNothingInNonTargetsAndForgetRemovedTargets) {
  Recognizer rec = MakeRecognizer(WordsOptions());
  for (const char* other : {"fruits.jpg", "baboon.jpg"}) {
    const cv::Mat target = PrepareTarget(Sample(other), 320);
    for (int i = 0; i < 3; ++i) {
      const RecognitionResult r = rec.Recognize(MakeSceneView(target, SceneOptions{}, 3000 + i).image);
      EXPECT_TRUE(r.found.empty()) << other << " view " << i << ": " << r.found[0].id << " " << r.found[0].inliers;
    }
  }
  // A view the word search finds (it finds 5-9 of 10, see above): the test
  // is about forgetting, so take the first of ten that is found.
  const cv::Mat& img = images_->at("building");
  SceneView v;
  bool seen = false;
  for (std::uint64_t seed = 4000; seed < 4010 && !seen; ++seed) {
    v = MakeSceneView(img, SceneOptions{}, seed);
    seen = Find(rec.Recognize(v.image), "building");
  }
  ASSERT_TRUE(seen) << "none of 10 views of 'building' recognised";
  const std::size_t before = rec.memory_bytes();
  EXPECT_TRUE(rec.Remove("building"));
  EXPECT_LT(rec.memory_bytes(), before);
  EXPECT_FALSE(Find(rec.Recognize(v.image), "building"));
  EXPECT_THROW(rec.RecognizeOne(v.image, "building"), Error);
  rec.Add("building", models_->at("building"));
  EXPECT_TRUE(Find(rec.Recognize(v.image), "building"));
  // Focus on one target is the full search restricted to its postings: the
  // same pose, and nothing for a target that is not there.
  const RecognitionResult one = rec.RecognizeOne(v.image, "building");
  ASSERT_EQ(one.found.size(), 1u);
  // Find points into the result: keep it alive (a temporary here was a
  // use after free, found by the sanitizer build).
  const RecognitionResult all = rec.Recognize(v.image);
  const Recognition* full = Find(all, "building");
  ASSERT_TRUE(full);
  EXPECT_EQ(one.found[0].inliers, full->inliers);
  EXPECT_LT(cv::norm(cv::Mat(one.found[0].homography), cv::Mat(full->homography), cv::NORM_INF), 1e-9);
  EXPECT_TRUE(rec.RecognizeOne(v.image, "coffee").found.empty());
}

TEST_F(RecognizerTest, WordsAreDeterministicAndCheckTheVocabulary) {
  ExpectDeterministic(MakeRecognizer(WordsOptions()));
  // A vocabulary of other dimensions cannot hold these models.
  const Vocabulary eight(std::vector<float>(8 * 16, 0.5f), 8);
  Recognizer bad(WordsOptions(), &eight);
  EXPECT_THROW(bad.Add("coffee", models_->at("coffee")), Error);
  EXPECT_EQ(bad.size(), 0u);
  RecognizerOptions o = WordsOptions();
  o.max_locations = 300;
  EXPECT_THROW(o.Check(), Error);
}

TEST_F(RecognizerTest, WordEncodingsRoundTripAndAreChecked) {
  const Recognizer direct = MakeRecognizer(WordsOptions());
  Recognizer loaded(WordsOptions());
  for (const auto& [id, m] : *models_) {
    const std::vector<std::uint8_t> bytes = direct.Encode(m);
    EXPECT_LT(bytes.size(), 8192u) << id;
    loaded.AddEncoded(id, bytes.data(), bytes.size());
  }
  // The same postings: the same answers.
  for (const char* id : {"starry_night", "building"}) {
    const SceneView v = MakeSceneView(images_->at(id), SceneOptions{}, 6000);
    const RecognitionResult a = direct.Recognize(v.image), b = loaded.Recognize(v.image);
    ASSERT_EQ(a.found.size(), b.found.size()) << id;
    for (std::size_t k = 0; k < a.found.size(); ++k) {
      EXPECT_EQ(a.found[k].id, b.found[k].id);
      EXPECT_EQ(a.found[k].inliers, b.found[k].inliers);
    }
    EXPECT_EQ(a.matches, b.matches);
  }
  std::vector<std::uint8_t> bytes = direct.Encode(models_->at("coffee"));
  Recognizer other(WordsOptions());
  std::vector<std::uint8_t> corrupt = bytes;
  corrupt[corrupt.size() / 2] ^= 0x10;
  EXPECT_THROW(other.AddEncoded("c", corrupt.data(), corrupt.size()), Error);
  EXPECT_THROW(other.AddEncoded("c", bytes.data(), bytes.size() - 5), Error);
  EXPECT_THROW(loaded.AddEncoded("coffee", bytes.data(), bytes.size()), Error);  // duplicate id
  // Another vocabulary or other word settings: refused, so the caller encodes again.
  std::vector<float> words(20 * 64);
  for (std::size_t k = 0; k < words.size(); ++k) words[k] = float(k % 7) - 3.f;
  const Vocabulary small(words, 20);
  Recognizer with_small(WordsOptions(), &small);
  EXPECT_THROW(with_small.AddEncoded("c", bytes.data(), bytes.size()), Error);
  RecognizerOptions fewer = WordsOptions();
  fewer.words_per_location = 3;
  Recognizer with_fewer(fewer);
  EXPECT_THROW(with_fewer.AddEncoded("c", bytes.data(), bytes.size()), Error);
  EXPECT_EQ(other.size() + with_small.size() + with_fewer.size(), 0u);
  EXPECT_THROW(Recognizer().Encode(models_->at("coffee")), Error);  // kExact has no encoding
}

}  // namespace
}  // namespace mvkp
