// mvkp video DB VIDEO|CAMERA_INDEX: recognition over a video with temporal
// focus (thesis §6.3.1), every target in view at once (VideoFollower): a
// target found by the full search is followed, looked for alone (focused) in
// the next frames until N consecutive misses, while the full search runs
// every --search-every frames for new ones. With --track klt (the default)
// the frames between detections are answered by optical-flow tracking of
// each target (mvkp/track), checked by the recogniser every --redetect-every
// frames and whenever tracking fails.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <set>

#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "commands.h"
#include "mvkp/recognize/target_db.h"
#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/db/target_store.h"
#include "mvkp/model/model.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/track/follower.h"
#include "output.h"
#include "pose_cli.h"

namespace mvkp::cli {
namespace {

struct VideoArgs {
  std::string db, source, output;
  bool json = false;
  int lose_after = 3;     // consecutive misses of a followed target before it is no longer followed
  int search_every = FollowerOptions{}.search_every;  // frames between full searches while targets are followed
  int max_frames = 0;     // 0: all
  bool no_focus = false;  // full search on every frame (for comparison)
  std::string track = "klt";  // klt | none
  int redetect_every = TrackerOptions{}.redetect_every;
  PoseSupport pose;       // --camera, --width-m
};

int RunVideo(VideoArgs& a) {
  Require(a.lose_after >= 1, ErrorCode::kInvalidArgument, "--lose-after must be >= 1");
  Require(a.search_every >= 1, ErrorCode::kInvalidArgument, "--search-every must be >= 1");
  Require(a.track == "klt" || a.track == "none", ErrorCode::kInvalidArgument,
          "--track must be klt or none, not '" + a.track + "'");
  Require(a.redetect_every >= 0, ErrorCode::kInvalidArgument, "--redetect-every must be >= 0");
  FollowerOptions fo;
  fo.focus = !a.no_focus;
  fo.lose_after = a.lose_after;
  fo.search_every = a.search_every;
  fo.track = a.track == "klt";
  fo.tracker.redetect_every = a.redetect_every;
  fo.Check();
  a.pose.Load();  // a bad --camera file fails before any work
  Timer load;
  const TargetStore store = TargetStore::Open(a.db);
  std::map<std::string, std::string> titles;
  Recognizer rec;
  std::map<std::string, cv::Size> sizes;
  std::vector<SkippedTarget> skipped;
  LoadTargets(
      store, rec, a.db,
      [&](const TargetInfo& info, int width, int height) {
        a.pose.AddTarget(info.id, info.meta, width, height, a.db);
        sizes[info.id] = cv::Size(width, height);
        titles[info.id] = info.title.empty() ? info.id : info.title;
      },
      &skipped);
  for (const auto& s : skipped) std::fprintf(stderr, "warning: skipped a target: %s\n", s.error.c_str());
  Require(rec.size() > 0, ErrorCode::kInvalidArgument, a.db + ": DB has no targets");
  const double load_ms = load.ElapsedMs();

  cv::VideoCapture cap;
  const bool camera = !a.source.empty() && std::all_of(a.source.begin(), a.source.end(), ::isdigit);
  if (camera) cap.open(std::stoi(a.source));
  else cap.open(a.source);
  Require(cap.isOpened(), ErrorCode::kIo,
          camera ? "camera " + a.source + ": cannot be opened" : a.source + ": cannot open video");
  cv::VideoWriter writer;
  VideoFollower follower(rec, fo);
  for (const auto& [id, size] : sizes) follower.SetObjectSize(id, size);
  int frames = 0, found_frames = 0, focus_frames = 0, tracked_frames = 0, lost = 0;
  std::size_t most = 0;           // targets in one frame
  std::set<std::string> found_ids;
  bool seen = false, prev_found = false;
  std::vector<double> ms;
  cv::Mat frame, gray;
  while ((a.max_frames <= 0 || frames < a.max_frames) && cap.read(frame) && !frame.empty()) {
    if (frame.channels() == 3) cv::cvtColor(frame, gray, cv::COLOR_BGR2GRAY);
    else if (frame.channels() == 4) cv::cvtColor(frame, gray, cv::COLOR_BGRA2GRAY);
    else gray = frame;
    if (a.pose.enabled()) a.pose.Camera(gray.size(), a.source);  // another aspect ratio: an error before any work
    const FollowedFrame r = follower.Process(gray);
    std::vector<std::optional<Pose>> poses;
    for (const auto& x : r.found) poses.push_back(a.pose.Estimate(x, gray.size(), a.source));
    const double t = r.ms;  // wall clock: recogniser and tracker
    ms.push_back(t);
    const bool found = !r.found.empty();
    most = std::max(most, r.found.size());
    for (const auto& x : r.found) found_ids.insert(x.id);
    if (found) {
      ++found_frames;
      seen = true;
    }
    if (seen && prev_found && !found) ++lost;
    prev_found = found;
    focus_frames += r.mode == FrameMode::kFocus;
    tracked_frames += r.mode == FrameMode::kTrack;
    if (a.json) {
      nlohmann::json f = nlohmann::json::array();
      for (std::size_t k = 0; k < r.found.size(); ++k) {
        const Recognition& x = r.found[k];
        nlohmann::json outline = nlohmann::json::array();
        for (const auto& p : x.outline) outline.push_back({p.x, p.y});
        f.push_back({{"id", x.id}, {"title", titles[x.id]}, {"outline", outline}, {"inliers", x.inliers},
                     {"tracked", bool(r.by_tracker[k])}});
        if (poses[k]) f.back()["pose"] = PoseSupport::Json(*poses[k]);
      }
      std::cout << nlohmann::json{{"frame", frames}, {"mode", FrameModeName(r.mode)}, {"found", f}, {"time_ms", t}}.dump()
                << "\n";
    }
    if (!a.output.empty()) {
      cv::Mat out;
      if (frame.channels() == 1) cv::cvtColor(frame, out, cv::COLOR_GRAY2BGR);
      else if (frame.channels() == 4) cv::cvtColor(frame, out, cv::COLOR_BGRA2BGR);
      else out = frame.clone();
      for (const auto& x : r.found) {
        std::vector<cv::Point> poly;
        for (const auto& p : x.outline) poly.emplace_back(int(std::lround(p.x)), int(std::lround(p.y)));
        cv::polylines(out, poly, true, cv::Scalar(0, 255, 0), 3, cv::LINE_AA);
        cv::putText(out, titles[x.id], poly[0] + cv::Point(4, 24), cv::FONT_HERSHEY_SIMPLEX, 0.8, cv::Scalar(0, 255, 0), 2,
                    cv::LINE_AA);
      }
      for (std::size_t k = 0; k < r.found.size(); ++k)
        if (poses[k]) a.pose.DrawAxes(out, r.found[k].id, *poses[k], gray.size(), a.source);
      if (!writer.isOpened()) {
        const double fps = cap.get(cv::CAP_PROP_FPS) > 0 ? cap.get(cv::CAP_PROP_FPS) : 25.0;
        writer.open(a.output, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps, out.size());
        Require(writer.isOpened(), ErrorCode::kIo, a.output + ": cannot write video");
      }
      writer.write(out);
    }
    ++frames;
  }
  Require(frames > 0, ErrorCode::kIo, (camera ? "camera " : "") + a.source + ": no frames");
  std::vector<double> sorted = ms;
  std::sort(sorted.begin(), sorted.end());
  double mean = 0;
  for (double v : ms) mean += v;
  mean /= ms.size();
  const nlohmann::json summary = {{"frames", frames},
                                  {"found_frames", found_frames},
                                  {"focus_frames", focus_frames},
                                  {"tracked_frames", tracked_frames},
                                  {"track", a.track},
                                  {"lost_after_found", lost},
                                  {"most_in_frame", most},
                                  {"found_ids", found_ids},
                                  {"median_ms", sorted[sorted.size() / 2]},
                                  {"mean_ms", mean},
                                  {"max_ms", sorted.back()},
                                  {"targets", rec.size()},
                                  {"load_ms", load_ms}};
  if (a.json) std::cout << nlohmann::json{{"summary", summary}}.dump() << std::endl;
  else
    std::printf("%d frames: target found in %d (%d searched with focus, %d tracked), lost %d times after being found; "
                "%.2f ms median, %.2f mean, %.2f max per frame (%zu targets, loaded in %.0f ms)\n",
                frames, found_frames, focus_frames, tracked_frames, lost, sorted[sorted.size() / 2], mean, sorted.back(),
                rec.size(), load_ms);
  return 0;
}

}  // namespace

void RegisterVideo(CLI::App& app, int* code) {
  auto a = std::make_shared<VideoArgs>();
  auto* c = app.add_subcommand("video", "Recognise database targets in a video or camera, with temporal focus");
  c->add_option("DB", a->db, "target database (mvkp db)")->required();
  c->add_option("SOURCE", a->source, "video file, or a camera index such as 0")->required();
  c->add_option("-o,--output", a->output, "write the annotated video here (.mp4)");
  c->add_flag("--json", a->json, "one JSON object per frame, then a summary object");
  c->add_option("--lose-after", a->lose_after, "misses of a followed target before it is no longer followed")
      ->capture_default_str();
  c->add_option("--search-every", a->search_every,
                "while targets are followed, the full search for new ones runs every N frames (1: every frame)")
      ->capture_default_str();
  c->add_option("--max-frames", a->max_frames, "stop after this many frames (0: all)")->capture_default_str();
  c->add_flag("--no-focus", a->no_focus, "full search on every frame");
  c->add_option("--track", a->track, "between detections: klt (optical-flow tracking) or none")->capture_default_str();
  c->add_option("--redetect-every", a->redetect_every,
                "--track klt: run the recogniser every N tracked frames to correct drift (0: only when tracking fails)")
      ->capture_default_str();
  a->pose.AddOptions(c);
  c->callback([a, code] { *code = RunVideo(*a); });
}

}  // namespace mvkp::cli
