// Options structs and enums of the matching side of mvkp, bound field by field
// (def_readwrite) so every keyword argument is a C++ field with its C++
// default. The field lists (fields/*.inc) are generated from the headers at
// build time (tools/gen_fields.py); tests/test_options_drift.py checks names
// and defaults against the headers.
#include <pybind11/functional.h>

#include "common.h"
#include "mvkp/augment/augment.h"
#include "mvkp/cdikp/cdikp.h"
#include "mvkp/index/ffva.h"
#include "mvkp/local/local_features.h"
#include "mvkp/local/pair_match.h"
#include "mvkp/match/matcher.h"
#include "mvkp/quality/quality.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/synth/camera_view.h"
#include "mvkp/synth/synth.h"
#include "mvkp/train/trainer.h"

namespace mvkp::py_bindings {

void BindOptions(py::module_& m) {
  BindEnum<Selection>(m, "Selection", {{"stability", Selection::kStability}, {"rifs", Selection::kRifs}},
                      "How view tracks are ranked before the best are kept (TrainOptions.select).");
  BindEnum<ViewModel>(m, "ViewModel", {{"mixed", ViewModel::kMixed}, {"camera", ViewModel::kCamera}, {"affine", ViewModel::kAffine}},
                      "Training views per pyramid level: affine + steep camera views, camera views only, or the thesis's affine views (TrainOptions.view_model).");
  BindEnum<GeometryModel>(m, "GeometryModel", {{"homography", GeometryModel::kHomography}, {"affine", GeometryModel::kAffine}},
                          "Geometry verified by the robust fit (MatchOptions.geometry).");
  BindEnum<RobustMethod>(m, "RobustMethod",
                         {{"ransac", RobustMethod::kRansac}, {"fast", RobustMethod::kFast},
                          {"accurate", RobustMethod::kAccurate}, {"magsac", RobustMethod::kMagsac},
                          {"prosac", RobustMethod::kProsac}},
                         "Robust estimator from OpenCV's calib3d (MatchOptions.robust).");
  BindEnum<RecognizerSearch>(m, "RecognizerSearch", {{"words", RecognizerSearch::kWords}, {"exact", RecognizerSearch::kExact}},
                             "Recognition search: exact (one FFVA index over all centres) or words (inverted file).");
  BindEnum<AugmentMetric>(m, "AugmentMetric",
                          {{"spearman", AugmentMetric::kSpearman}, {"kendall", AugmentMetric::kKendall}, {"count", AugmentMetric::kCount}},
                          "Similarity of ordinal codes (augmented features).");
  BindEnum<TieMode>(m, "TieMode", {{"local", TieMode::kLocal}, {"global_", TieMode::kGlobal}},
                    "How ties in relative features are broken (augmented features).");

  py::class_<TrainOptions> train(m, "TrainOptions", "mvkp::TrainOptions: how a target is trained from one image.");
  BindEnum<TrainOptions::StatsViews>(train, "StatsViews",
                                     {{"all", TrainOptions::StatsViews::kAll}, {"rotation", TrainOptions::StatsViews::kRotation},
                                      {"general", TrainOptions::StatsViews::kGeneral}},
                                     "Which views' descriptors give a track's mean, DS and VS.");
  train
#include "fields/TrainOptions.inc"
      ;
  AddOptionsMethods(train);
  train.def("check", &TrainOptions::Check, "Raises InvalidArgumentError naming the first bad option.");

  py::class_<MatchOptions> match(m, "MatchOptions", "mvkp::MatchOptions: how a trained target is searched in a frame.");
  match
#include "fields/MatchOptions.inc"
      ;
  AddOptionsMethods(match);
  match.def("check", &MatchOptions::Check, "Raises InvalidArgumentError naming the first bad option.");

  py::class_<RecognizerOptions> rec(m, "RecognizerOptions", "mvkp::RecognizerOptions: multi-target recognition.");
  rec
#include "fields/RecognizerOptions.inc"
      ;
  AddOptionsMethods(rec);
  rec.def("check", &RecognizerOptions::Check, "Raises InvalidArgumentError naming the first bad option.");
  rec.def_static("words", &RecognizerOptions::Words, "The word search with its own query budget (600 points).");
  m.def("recognition_match_defaults", &RecognitionMatchDefaults, "The MatchOptions recognition starts from (1000 points, dynamic ratio).");

  py::class_<FfvaOptions> ffva(m, "FfvaOptions", "mvkp::FfvaOptions: FFVA exact kNN index layout.");
  BindEnum<FfvaOptions::Filter>(ffva, "Filter", {{"exact", FfvaOptions::Filter::kExact}, {"approx", FfvaOptions::Filter::kApprox}}, "exact: lower-bound filter (results equal brute force); approx: the thesis block distance.");
  ffva
#include "fields/FfvaOptions.inc"
      ;
  AddOptionsMethods(ffva);

  py::class_<IndexLoadOptions> ilo(m, "IndexLoadOptions", "mvkp::IndexLoadOptions: how an index file is loaded.");
  ilo
#include "fields/IndexLoadOptions.inc"
      ;
  AddOptionsMethods(ilo);

  py::class_<CdikpOptions> cdikp(m, "CdikpOptions", "mvkp::CdikpOptions: the CDIKP descriptor and its SIFT detector.");
  cdikp
#include "fields/CdikpOptions.inc"
      ;
  AddOptionsMethods(cdikp);
  cdikp.def("check", &CdikpOptions::Check);

  py::class_<AugmentOptions> aug(m, "AugmentOptions", "mvkp::AugmentOptions: augmented features (ordinal codes of sub-images).");
  aug
#include "fields/AugmentOptions.inc"
      ;
  AddOptionsMethods(aug);
  aug.def("check", &AugmentOptions::Check);

  py::class_<LocalFeatureOptions> local(m, "LocalFeatureOptions", "mvkp::LocalFeatureOptions: pair matching with cdikp, sift, orb, akaze, aug-sift, aug-cdikp.");
  local
#include "fields/LocalFeatureOptions.inc"
      ;
  AddOptionsMethods(local);

  py::class_<PairMatchOptions> pairo(m, "PairMatchOptions", "mvkp::PairMatchOptions: ratio test and RANSAC of local-feature pair matching.");
  pairo
#include "fields/PairMatchOptions.inc"
      ;
  AddOptionsMethods(pairo);

  py::class_<SceneOptions> scene(m, "SceneOptions", "mvkp::SceneOptions: synthetic test views with known homography.");
  scene
#include "fields/SceneOptions.inc"
      ;
  AddOptionsMethods(scene);
  scene.def("check", &SceneOptions::Check);

  py::class_<CameraSceneOptions> cscene(m, "CameraSceneOptions",
                                       "mvkp::CameraSceneOptions: camera-model test frames (mvkp eval sweep, quality).");
  cscene
#include "fields/CameraSceneOptions.inc"
      ;
  AddOptionsMethods(cscene);
  cscene.def("check", &CameraSceneOptions::Check);

  py::class_<QualityOptions> quality(m, "QualityOptions", "mvkp::QualityOptions: target quality assessment.");
  quality
#include "fields/QualityOptions.inc"
      ;
  AddOptionsMethods(quality);
  quality.def("check", &QualityOptions::Check);
}

}  // namespace mvkp::py_bindings
