#include "mvkp/serve/encode.h"

#include "mvkp/db/json_limits.h"

namespace mvkp::serve {

using Json = nlohmann::json;

Json RecognitionJson(const Recognition& f, const std::string& title) {
  Json h = Json::array(), outline = Json::array();
  for (int i = 0; i < 3; ++i) h.push_back({f.homography(i, 0), f.homography(i, 1), f.homography(i, 2)});
  for (const auto& p : f.outline) outline.push_back({p.x, p.y});
  return {{"id", f.id},           {"title", title},   {"homography", h}, {"outline", outline},
          {"inliers", f.inliers}, {"votes", f.votes}, {"score", f.score}};
}

Json QualityJson(const QualityReport& r, bool with_points) {
  Json factors = Json::object(), reasons = Json::array();
  for (const auto& f : r.factors)
    factors[f.name] = {{"value", f.value},   {"factor", f.factor}, {"weight", f.weight},
                       {"points", f.points}, {"max_points", 100 * f.weight}, {"lost", f.lost}};
  for (const auto& q : r.reasons) reasons.push_back({{"code", q.code}, {"message", q.message}, {"lost", q.lost}});
  Json j = {{"score", r.score},
            {"verdict", r.verdict},
            {"expected_detection_rate", r.detection_rate},
            {"test_views", r.test_views},
            {"median_error_px", r.median_error_px},
            {"stable_points", r.eligible_tracks},
            {"stable_points_side", r.train_side},
            {"selected_points", r.selected_tracks},
            {"factors", factors},
            {"reasons", reasons},
            {"time_ms", r.ms}};
  if (with_points) {
    Json sel = Json::array();
    for (const auto& p : r.selected) sel.push_back({p.x, p.y});
    j["selected"] = sel;
  }
  return j;
}

Json DatabaseQualityJson(const DatabaseQualityReport& r) {
  Json ex = Json::array(), pairs = Json::array();
  for (const auto& e : r.exhibits) {
    Json j = {{"id", e.info.id},
              {"title", e.info.title},
              {"added_at", e.info.added_at},
              {"quality", e.assessed ? QualityJson(e.quality, /*with_points=*/false) : Json(nullptr)},
              {"time_ms", {{"quality", e.quality_ms}, {"probe", e.probe_ms}}}};
    if (!e.error.empty()) j["error"] = e.error;
    ex.push_back(std::move(j));
  }
  for (const auto& p : r.pairs)
    pairs.push_back({{"a", p.a}, {"b", p.b}, {"found_in", p.found_in}, {"probes", p.probes}, {"inliers", p.inliers}});
  return {{"db", r.db}, {"exhibits", ex}, {"lookalikes", pairs}, {"time_ms", r.ms}};
}

Json PoseJson(const Pose& p) {
  Json R = Json::array();
  for (int i = 0; i < 3; ++i) R.push_back({p.R(i, 0), p.R(i, 1), p.R(i, 2)});
  return {{"rvec", {p.rvec[0], p.rvec[1], p.rvec[2]}},
          {"tvec", {p.tvec[0], p.tvec[1], p.tvec[2]}},
          {"R", R},
          {"distance_m", p.distance},
          {"reprojection_px", p.reprojection_px}};
}

Json InfoJson(const TargetInfo& t) {
  Json meta;
  if (!TryParseJsonLimited(t.meta, meta, MetaJsonLimits()) || !meta.is_object()) meta = Json::object();
  return {{"id", t.id},   {"title", t.title}, {"artist", t.artist}, {"year", t.year},         {"url", t.url},
          {"meta", meta}, {"width", t.width}, {"height", t.height}, {"added_at", t.added_at}};
}

std::string Dump(const Json& j) { return j.dump(-1, ' ', false, Json::error_handler_t::replace); }

}  // namespace mvkp::serve
