// The JSON forms in which mvkp answers: the guide service's responses and the
// CLI's --json output share them, so a client reads one shape everywhere.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "mvkp/db/target_store.h"
#include "mvkp/pose/pose.h"
#include "mvkp/quality/db_quality.h"
#include "mvkp/quality/quality.h"
#include "mvkp/recognize/recognizer.h"

namespace mvkp::serve {

// One found target: id, title, homography, outline, inliers, votes, score.
nlohmann::json RecognitionJson(const Recognition& f, const std::string& title);

// A target quality report: score, verdict, expected detection rate, factors
// (with points), reasons, time_ms; the selected feature positions only when
// `with_points`.
nlohmann::json QualityJson(const QualityReport& r, bool with_points);

// A database's quality (`mvkp quality DB --json`, GET /api/admin/quality):
// {"db", "exhibits": [{"id", "title", "added_at", "quality" (QualityJson
// without points) or null, "error" (if any), "time_ms": {"quality", "probe"}}],
// "lookalikes": [{"a", "b", "found_in", "probes", "inliers"}], "time_ms"}.
// A look-alike: exhibit b was found in `found_in` of `probes` recognitions of
// a's stored image and views.
nlohmann::json DatabaseQualityJson(const DatabaseQualityReport& r);

// {"rvec", "tvec" (metres, camera frame), "R", "distance_m", "reprojection_px"}.
nlohmann::json PoseJson(const Pose& p);

// An exhibit's metadata: id, title, artist, year, url, meta (an object; {}
// for a stored meta that is not one within MetaJsonLimits), width, height,
// added_at.
nlohmann::json InfoJson(const TargetInfo& t);

// JSON text in which invalid UTF-8 of stored strings becomes U+FFFD instead
// of an exception.
std::string Dump(const nlohmann::json& j);

}  // namespace mvkp::serve
