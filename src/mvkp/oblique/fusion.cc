#include "mvkp/oblique/fusion.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

void FusionOptions::Check() const {
  roi.Check();
  region_shape.Check();
  group_shape.Check();
  Require(work_px == 0 || (work_px >= 64 && work_px <= 16384), ErrorCode::kInvalidArgument,
          "FusionOptions.work_px must be 0 or in [64, 16384]");
  Require(min_edgelet_px >= 1 && max_edgelet_px >= 2 * min_edgelet_px && max_edgelet_px <= 1000,
          ErrorCode::kInvalidArgument, "FusionOptions: need 1 <= min_edgelet_px, 2 x min <= max_edgelet_px <= 1000");
  Require(label_radius_px >= 1 && label_radius_px <= 100 && second_label >= 1 && second_label <= 10,
          ErrorCode::kInvalidArgument, "FusionOptions: label_radius_px in [1, 100], second_label in [1, 10]");
  Require(second_peak > 0 && second_peak <= 1 && link_px > 0 && link_px <= 100, ErrorCode::kInvalidArgument,
          "FusionOptions: second_peak in (0, 1], link_px in (0, 100]");
  Require(min_list_edgelets >= 3 && min_list_edgelets <= 1000 && list_partials >= 0 && list_partials <= 16,
          ErrorCode::kInvalidArgument, "FusionOptions: min_list_edgelets in [3, 1000], list_partials in [0, 16]");
  Require(partial_corners >= 4 && max_partials >= 0 && max_partials <= 16, ErrorCode::kInvalidArgument,
          "FusionOptions: partial_corners >= 4, max_partials in [0, 16]");
  Require(shortlist >= 2 && shortlist <= 10000 && max_cost > 0 && max_cost <= 1 && candidates >= 1 && candidates <= 100 && max_cost_ratio > 0 &&
              max_cost_ratio <= 1 && max_matches >= 1 && pair_step >= 1,
          ErrorCode::kInvalidArgument,
          "FusionOptions: shortlist >= 2, max_cost and max_cost_ratio in (0, 1], max_matches >= 1, pair_step >= 1");
}

namespace {

using Polyline = std::vector<cv::Point2f>;

double Length(const Edgelet& e) { return cv::norm(e.b - e.a); }

// Edgelets of the working image: LSD segments cut into pieces no longer
// than max_edgelet_px.
std::vector<Edgelet> DetectEdgelets(const cv::Mat& gray, const FusionOptions& o) {
  std::vector<cv::Vec4f> segs;
  cv::createLineSegmentDetector(cv::LSD_REFINE_STD)->detect(gray, segs);
  std::vector<Edgelet> out;
  for (const cv::Vec4f& s : segs) {
    const cv::Point2f a(s[0], s[1]), b(s[2], s[3]);
    const double len = cv::norm(b - a);
    if (!(len >= o.min_edgelet_px)) continue;
    const int n = std::max(1, int(std::ceil(len / o.max_edgelet_px)));
    for (int k = 0; k < n; ++k) {
      Edgelet e;
      e.a = a + (b - a) * float(double(k) / n);
      e.b = a + (b - a) * float(double(k + 1) / n);
      out.push_back(e);
    }
  }
  return out;
}

// Membership labels (§7.3.2): every pixel an edgelet covers votes for the
// nearest region within the radius and for others nearly as near; the
// edgelet takes its vote histogram's first peak, and the second when close.
void LabelEdgelets(const cv::Mat1i& labels, const FusionOptions& o, std::vector<Edgelet>* edgelets) {
  const int r = int(std::ceil(o.label_radius_px));
  const double r2 = o.label_radius_px * o.label_radius_px, ratio2 = o.second_label * o.second_label;
  std::vector<std::pair<int, int>> near;   // (label, squared distance)
  std::vector<std::pair<int, int>> votes;  // (label, count)
  for (Edgelet& e : *edgelets) {
    votes.clear();
    const double len = Length(e);
    const int steps = std::max(1, int(std::ceil(len)));
    for (int s = 0; s <= steps; ++s) {
      const cv::Point2f p = e.a + (e.b - e.a) * float(double(s) / steps);
      const int cx = int(std::lround(p.x)), cy = int(std::lround(p.y));
      near.clear();
      for (int y = std::max(0, cy - r); y <= std::min(labels.rows - 1, cy + r); ++y) {
        const int* row = labels[y];
        for (int x = std::max(0, cx - r); x <= std::min(labels.cols - 1, cx + r); ++x) {
          const int l = row[x];
          if (l <= 0) continue;
          const int d2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
          if (d2 > r2) continue;
          auto it = std::find_if(near.begin(), near.end(), [l](const auto& q) { return q.first == l; });
          if (it == near.end())
            near.emplace_back(l, d2);
          else
            it->second = std::min(it->second, d2);
        }
      }
      if (near.empty()) continue;
      int best = near[0].second;
      for (const auto& q : near) best = std::min(best, q.second);
      for (const auto& q : near) {
        if (q.second > std::max(1.0, best * ratio2)) continue;
        auto it = std::find_if(votes.begin(), votes.end(), [&](const auto& v) { return v.first == q.first; });
        if (it == votes.end())
          votes.emplace_back(q.first, 1);
        else
          ++it->second;
      }
    }
    if (votes.empty()) continue;
    std::sort(votes.begin(), votes.end(),
              [](const auto& x, const auto& y) { return x.second > y.second || (x.second == y.second && x.first < y.first); });
    e.label = votes[0].first - 1;
    if (votes.size() > 1 && votes[1].second >= o.second_peak * votes[0].second) e.label2 = votes[1].first - 1;
  }
}

// Ordered edgelet lists of one group (indices into `all`, each edgelet
// oriented along its list): start at the edgelet with an end nearest the
// group's bounding-box corner, grow forward from the outgoing end, then
// backward from the first end, by the nearest end within link_px.
std::vector<std::vector<Edgelet>> OrderLists(const std::vector<Edgelet>& group, double link_px) {
  std::vector<std::vector<Edgelet>> lists;
  std::vector<char> used(group.size(), 0);
  std::size_t left = group.size();
  float x0 = 1e30f, y0 = 1e30f;
  for (const Edgelet& e : group) x0 = std::min({x0, e.a.x, e.b.x}), y0 = std::min({y0, e.a.y, e.b.y});
  const cv::Point2f corner(x0, y0);
  const double link2 = link_px * link_px;
  auto d2 = [](cv::Point2f p, cv::Point2f q) { return double((p - q).dot(p - q)); };
  // the unused edgelet with an end nearest p (oriented to start there), or -1
  auto nearest = [&](cv::Point2f p, double limit2, Edgelet* out) {
    int best = -1;
    double bd = limit2;
    bool flip = false;
    for (std::size_t i = 0; i < group.size(); ++i) {
      if (used[i]) continue;
      const double da = d2(group[i].a, p), db = d2(group[i].b, p);
      if (da <= bd) bd = da, best = int(i), flip = false;
      if (db < bd) bd = db, best = int(i), flip = true;
    }
    if (best >= 0) {
      *out = group[std::size_t(best)];
      if (flip) std::swap(out->a, out->b);
    }
    return best;
  };
  while (left > 0) {
    Edgelet e;
    int i = nearest(corner, 1e30, &e);
    used[std::size_t(i)] = 1, --left;
    std::vector<Edgelet> list{e};
    const cv::Point2f start = e.a;
    while (left > 0) {
      if (list.size() >= 3 && d2(list.back().b, start) <= link2) break;  // closed
      i = nearest(list.back().b, link2, &e);
      if (i < 0) break;
      used[std::size_t(i)] = 1, --left;
      list.push_back(e);
    }
    const bool closed = list.size() >= 3 && d2(list.back().b, start) <= link2;
    std::vector<Edgelet> head;
    while (!closed && left > 0) {
      i = nearest(head.empty() ? list.front().a : head.back().a, link2, &e);
      if (i < 0) break;
      used[std::size_t(i)] = 1, --left;
      std::swap(e.a, e.b);  // it ends where the list starts
      head.push_back(e);
    }
    std::reverse(head.begin(), head.end());
    head.insert(head.end(), list.begin(), list.end());
    lists.push_back(std::move(head));
  }
  return lists;
}

// Point at arc length s of a polyline with cumulative lengths cum.
cv::Point2f At(const Polyline& p, const std::vector<double>& cum, double s) {
  s = std::clamp(s, 0.0, cum.back());
  std::size_t k = std::size_t(std::upper_bound(cum.begin(), cum.end(), s) - cum.begin());
  k = std::clamp<std::size_t>(k, 1, p.size() - 1);
  const double sl = cum[k] - cum[k - 1], t = sl > 0 ? (s - cum[k - 1]) / sl : 0.0;
  return p[k - 1] + (p[k] - p[k - 1]) * float(t);
}

// The descriptor of an ordered run of edgelets (§7.3.2): N_VAP anchors
// evenly along the run, histograms of the edgelets' midpoints weighted by
// their lengths, tangent frames, the run's minimum-area-rectangle diagonal.
ShapeDescriptor DescribeList(std::vector<Edgelet> run, const ShapeContextOptions& o) {
  Polyline poly;
  for (const Edgelet& e : run) poly.push_back(e.a), poly.push_back(e.b);
  if (SignedArea(poly) < 0) {  // traverse every list the same way round
    std::reverse(run.begin(), run.end());
    for (Edgelet& e : run) std::swap(e.a, e.b);
    std::reverse(poly.begin(), poly.end());
  }
  std::vector<double> cum(poly.size(), 0.0);
  for (std::size_t i = 1; i < poly.size(); ++i) cum[i] = cum[i - 1] + cv::norm(poly[i] - poly[i - 1]);
  const double len = cum.back();
  const cv::RotatedRect box = cv::minAreaRect(poly);
  const double diag = std::hypot(box.size.width, box.size.height);
  if (!(len > 1e-6) || !(diag > 1e-6)) return {};
  const int n = o.points;
  Polyline anchors(static_cast<std::size_t>(n));
  std::vector<double> tangents(static_cast<std::size_t>(n));
  const double step = len / n;
  for (int j = 0; j < n; ++j) {
    const double s = (j + 0.5) * step;
    anchors[std::size_t(j)] = At(poly, cum, s);
    const cv::Point2f t = At(poly, cum, s + o.tangent_span * step) - At(poly, cum, s - o.tangent_span * step);
    tangents[std::size_t(j)] = std::atan2(t.y, t.x);
  }
  Polyline mids;
  std::vector<float> weights;
  for (const Edgelet& e : run) mids.push_back((e.a + e.b) * 0.5f), weights.push_back(float(Length(e)));
  ShapeDescriptor d = DescribeAnchors(anchors, tangents, mids, weights, diag, o);
  d.area = std::abs(SignedArea(poly));
  return d;
}

void ScalePoints(ShapeDescriptor* d, float k) {
  for (auto& p : d->points) p *= k;
  d->scale *= k;
  d->area *= double(k) * k;
}

}  // namespace

FusionFeatures ExtractFusionFeatures(const cv::Mat& image, const FusionOptions& o) {
  o.Check();
  Require(!image.empty() && image.depth() == CV_8U && (image.channels() == 1 || image.channels() == 3),
          ErrorCode::kInvalidArgument, "ExtractFusionFeatures: an 8-bit grey or BGR image is required");
  Timer tm;
  FusionFeatures f;
  const int longer = std::max(image.cols, image.rows);
  const double s = o.work_px > 0 && longer > o.work_px ? double(o.work_px) / longer : 1.0;
  cv::Mat work;
  if (s < 1)
    cv::resize(image, work, cv::Size(), s, s, cv::INTER_AREA);
  else
    work = image;
  const float back = float(1 / s);
  cv::Mat gray;
  if (work.channels() == 3)
    cv::cvtColor(work, gray, cv::COLOR_BGR2GRAY);
  else
    gray = work;

  // ROI track
  cv::Mat1i labels;
  const std::vector<PhotoRegion> rois = SegmentOptical(work, o.roi, &labels);
  f.rois = int(rois.size());
  for (std::size_t i = 0; i < rois.size(); ++i) {
    Contour c(rois[i].contour.begin(), rois[i].contour.end());
    ShapeDescriptor d = DescribeContour(c, o.region_shape);
    if (d.empty()) continue;
    d.region = int(i);
    f.regions.push_back(std::move(d));
    for (ShapeDescriptor& p : DescribePartials(c, o.region_shape, o.partial_corners, o.max_partials)) {
      p.region = int(i);
      f.regions.push_back(std::move(p));
    }
    std::vector<cv::Point> in;
    for (const cv::Point& q : rois[i].contour) in.emplace_back(int(std::lround(q.x * back)), int(std::lround(q.y * back)));
    f.roi_contours.push_back(std::move(in));
  }
  for (ShapeDescriptor& d : f.regions) ScalePoints(&d, back);

  // edge-group track
  std::vector<Edgelet> edgelets = DetectEdgelets(gray, o);
  LabelEdgelets(labels, o, &edgelets);
  std::vector<std::vector<int>> groups(rois.size());
  for (std::size_t i = 0; i < edgelets.size(); ++i) {
    if (edgelets[i].label >= 0) groups[std::size_t(edgelets[i].label)].push_back(int(i));
    if (edgelets[i].label2 >= 0) groups[std::size_t(edgelets[i].label2)].push_back(int(i));
  }
  for (const std::vector<int>& g : groups) {
    std::vector<Edgelet> members;
    for (int i : g) members.push_back(edgelets[std::size_t(i)]);
    for (std::vector<Edgelet>& list : OrderLists(members, o.link_px)) {
      const int m = int(list.size());
      if (m < o.min_list_edgelets) continue;
      const int id = f.oels++;
      for (Edgelet& e : list) e.list = id;
      ShapeDescriptor d = DescribeList(list, o.group_shape);
      if (d.empty()) continue;
      d.region = id;
      f.lists.push_back(std::move(d));
      if (m >= 2 * o.min_list_edgelets) {
        const int run = std::max(o.min_list_edgelets, int(std::lround(0.6 * m)));
        for (int k = 0; k < o.list_partials; ++k) {
          const int start = o.list_partials > 1 ? (m - run) * k / (o.list_partials - 1) : 0;
          ShapeDescriptor p =
              DescribeList(std::vector<Edgelet>(list.begin() + start, list.begin() + start + run), o.group_shape);
          if (p.empty()) continue;
          p.region = id;
          p.partial = true;
          f.lists.push_back(std::move(p));
        }
      }
      for (Edgelet& e : list) f.edgelets.push_back({e.a * back, e.b * back, e.label, e.label2, id});
    }
  }
  for (ShapeDescriptor& d : f.lists) ScalePoints(&d, back);
  f.ms = tm.ElapsedMs();
  return f;
}

namespace {

struct FeaturePair {
  int view = 0, nadir = 0, shift = 0;
  double cost = 1, ratio = 1;
};

// Matches of one track (§7.3.2): first layer by mean histogram, then the
// best cyclic shift, then the cost ratio over another source feature.
std::vector<FeaturePair> MatchTrack(const std::vector<ShapeDescriptor>& nadir, const std::vector<ShapeDescriptor>& view,
                                    const FusionOptions& o) {
  std::vector<FeaturePair> out;
  if (nadir.empty() || view.empty()) return out;
  auto means = [](const std::vector<ShapeDescriptor>& ds) {
    cv::Mat m(int(ds.size()), ds[0].hist.cols, CV_32F);
    for (std::size_t i = 0; i < ds.size(); ++i) cv::reduce(ds[i].hist, m.row(int(i)), 0, cv::REDUCE_AVG);
    return m;
  };
  const cv::Mat mn = means(nadir), mv = means(view);
  std::vector<std::pair<float, int>> order(nadir.size());
  for (std::size_t a = 0; a < view.size(); ++a) {
    for (std::size_t b = 0; b < nadir.size(); ++b) order[b] = {float(cv::norm(mv.row(int(a)), mn.row(int(b)), cv::NORM_L2SQR)), int(b)};
    const std::size_t k = std::min<std::size_t>(std::size_t(o.shortlist), order.size());
    std::partial_sort(order.begin(), order.begin() + std::ptrdiff_t(k), order.end());
    // the best shift of each shortlisted candidate; one per source feature
    std::vector<FeaturePair> cand;
    for (std::size_t c = 0; c < k; ++c) {
      const int b = order[c].second;
      if (nadir[std::size_t(b)].hist.rows != view[a].hist.rows) continue;
      const ShiftCost sc = MatchDescriptors(view[a], nadir[std::size_t(b)]);
      cand.push_back({int(a), b, sc.shift, sc.cost, 1.0});
    }
    std::sort(cand.begin(), cand.end(), [](const FeaturePair& x, const FeaturePair& y) {
      return x.cost < y.cost || (x.cost == y.cost && x.nadir < y.nadir);
    });
    std::vector<FeaturePair> firsts;  // the best of each source, best first
    for (const FeaturePair& fp : cand) {
      const int src = nadir[std::size_t(fp.nadir)].region;
      if (std::none_of(firsts.begin(), firsts.end(), [&](const FeaturePair& q) { return nadir[std::size_t(q.nadir)].region == src; }))
        firsts.push_back(fp);
    }
    // the cost ratio (thesis): against the best of the next source; with
    // several candidates kept, against the first source not kept
    const std::size_t keep = std::min<std::size_t>(std::size_t(o.candidates), firsts.size());
    const double next = keep < firsts.size() ? firsts[keep].cost : 1.0;
    for (std::size_t i = 0; i < keep; ++i) {
      FeaturePair fp = firsts[i];
      fp.ratio = next > 0 ? fp.cost / next : 1.0;
      if (fp.cost <= o.max_cost && fp.ratio <= o.max_cost_ratio) out.push_back(fp);
    }
  }
  std::sort(out.begin(), out.end(), [](const FeaturePair& x, const FeaturePair& y) {
    return x.ratio < y.ratio || (x.ratio == y.ratio && x.view < y.view);
  });
  if (int(out.size()) > o.max_matches) out.resize(std::size_t(o.max_matches));
  return out;
}

}  // namespace

std::vector<NadirMatch> MatchFusion(const FusionFeatures& nadir, const FusionFeatures& view, const FusionOptions& o,
                                    FusionMatchStats* stats) {
  o.Check();
  Timer tm;
  const std::vector<FeaturePair> rp = MatchTrack(nadir.regions, view.regions, o);
  const std::vector<FeaturePair> lp = MatchTrack(nadir.lists, view.lists, o);
  std::vector<NadirMatch> out;
  std::vector<int> source;
  int id = 0;
  auto emit = [&](const std::vector<FeaturePair>& pairs, const std::vector<ShapeDescriptor>& nd,
                  const std::vector<ShapeDescriptor>& vd, int offset) {
    for (const FeaturePair& fp : pairs) {
      source.push_back(offset + vd[std::size_t(fp.view)].region);
      const ShapeDescriptor& a = vd[std::size_t(fp.view)];
      const ShapeDescriptor& b = nd[std::size_t(fp.nadir)];
      const int n = int(a.points.size());
      for (int j = 0; j < n; j += o.pair_step)
        out.push_back({b.points[std::size_t((j + fp.shift) % n)], a.points[std::size_t(j)], float(fp.cost), id});
      ++id;
    }
  };
  emit(rp, nadir.regions, view.regions, 0);
  emit(lp, nadir.lists, view.lists, kListSource);
  if (stats) *stats = {int(rp.size()), int(lp.size()), std::move(source), tm.ElapsedMs()};
  return out;
}

std::vector<CameraHypothesis> FeatureHypotheses(const std::vector<cv::Point3d>& world,
                                                const std::vector<cv::Point2d>& pixels,
                                                const std::vector<int>& pair_of, const std::vector<int>& view_source,
                                                const cv::Matx33d& K, int max_hypotheses,
                                                const FeatureConsensusOptions& o) {
  Require(world.size() == pixels.size() && world.size() == pair_of.size() && max_hypotheses >= 0 &&
              o.agree_px > 0 && o.agree_share > 0 && o.agree_share <= 1 && o.min_points >= 4,
          ErrorCode::kInvalidArgument, "FeatureHypotheses: bad arguments");
  int pairs = 0;
  for (int p : pair_of) {
    Require(p >= 0 && p < int(view_source.size()), ErrorCode::kInvalidArgument,
            "FeatureHypotheses: a pair index without a view source");
    pairs = std::max(pairs, p + 1);
  }
  std::vector<CameraHypothesis> out;
  if (world.empty() || max_hypotheses == 0) return out;
  cv::Point3d c0(0, 0, 0);  // centred: PnP on coordinates of hundreds of metres loses digits
  for (const auto& X : world) c0 += X;
  c0 *= 1.0 / double(world.size());
  std::vector<std::vector<int>> members(static_cast<std::size_t>(pairs));
  for (std::size_t i = 0; i < world.size(); ++i) members[std::size_t(pair_of[i])].push_back(int(i));
  const cv::Mat Km(K);
  std::vector<cv::Point3d> Xc;
  for (const auto& X : world) Xc.push_back(X - c0);
  std::vector<cv::Point2d> proj;
  // reprojection error of every point under (rvec, tvec), centred frame
  auto errors = [&](const cv::Mat& rvec, const cv::Mat& tvec, std::vector<double>* e) {
    cv::projectPoints(Xc, rvec, tvec, Km, cv::noArray(), proj);
    cv::Matx33d R;
    cv::Rodrigues(rvec, R);
    const cv::Vec3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    e->resize(world.size());
    for (std::size_t i = 0; i < world.size(); ++i) {
      const cv::Vec3d xc = R * cv::Vec3d(Xc[i].x, Xc[i].y, Xc[i].z) + t;
      (*e)[i] = xc[2] > 0 ? cv::norm(proj[i] - pixels[i]) : 1e9;
    }
  };
  // agreeing view features, and the flags of their points within agree_px
  auto agree = [&](const std::vector<double>& e, std::vector<char>* flags) {
    std::vector<int> srcs;
    flags->assign(world.size(), 0);
    for (int p = 0; p < pairs; ++p) {
      const auto& m = members[std::size_t(p)];
      if (m.empty()) continue;
      int in = 0;
      for (int i : m) in += e[std::size_t(i)] <= o.agree_px;
      if (in < o.agree_share * double(m.size())) continue;
      srcs.push_back(view_source[std::size_t(p)]);
      for (int i : m) (*flags)[std::size_t(i)] = e[std::size_t(i)] <= o.agree_px;
    }
    std::sort(srcs.begin(), srcs.end());
    return int(std::unique(srcs.begin(), srcs.end()) - srcs.begin());
  };
  auto looks_down = [&](const cv::Mat& rvec, const cv::Mat& tvec) {
    cv::Matx33d R;
    cv::Rodrigues(rvec, R);
    const cv::Vec3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    const cv::Vec3d centre = -(R.t() * t);
    return centre[2] > 5.0;  // metres above the points' mean height
  };
  struct Seed {
    int features, points, pair;
    cv::Mat r, t;
  };
  std::vector<Seed> seeds;
  std::vector<double> e;
  std::vector<char> flags;
  for (int p = 0; p < pairs; ++p) {
    const auto& m = members[std::size_t(p)];
    if (int(m.size()) < o.min_points) continue;
    std::vector<cv::Point3d> X;
    std::vector<cv::Point2d> x;
    for (int i : m) X.push_back(Xc[std::size_t(i)]), x.push_back(pixels[std::size_t(i)]);
    cv::Mat rvec, tvec;
    try {
      if (!cv::solvePnP(X, x, Km, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_SQPNP)) continue;
    } catch (const cv::Exception&) {
      continue;  // degenerate (collinear) points
    }
    if (!looks_down(rvec, tvec)) continue;
    errors(rvec, tvec, &e);
    const int n = agree(e, &flags);
    if (n == 0) continue;
    seeds.push_back({n, int(std::count(flags.begin(), flags.end(), 1)), p, rvec, tvec});
  }
  std::sort(seeds.begin(), seeds.end(), [](const Seed& a, const Seed& b) {
    return a.features > b.features || (a.features == b.features && (a.points > b.points || (a.points == b.points && a.pair < b.pair)));
  });
  for (const Seed& sd : seeds) {
    if (int(out.size()) >= max_hypotheses) break;
    cv::Mat r = sd.r.clone(), t = sd.t.clone();
    for (int round = 0; round < 2; ++round) {  // refit on the agreeing points
      errors(r, t, &e);
      agree(e, &flags);
      std::vector<cv::Point3d> X;
      std::vector<cv::Point2d> x;
      for (std::size_t i = 0; i < world.size(); ++i)
        if (flags[i]) X.push_back(Xc[i]), x.push_back(pixels[i]);
      if (X.size() < 6) break;
      cv::Mat r2 = r.clone(), t2 = t.clone();
      cv::solvePnPRefineLM(X, x, Km, cv::noArray(), r2, t2);
      if (!looks_down(r2, t2)) break;
      r = r2, t = t2;
    }
    CameraHypothesis h;
    errors(r, t, &e);
    h.features = agree(e, &h.agree);
    h.points = int(std::count(h.agree.begin(), h.agree.end(), 1));
    // a seed whose refit lands on a camera already proposed adds nothing
    if (std::any_of(out.begin(), out.end(), [&](const CameraHypothesis& q) { return q.agree == h.agree; })) continue;
    cv::Matx33d R;
    cv::Rodrigues(r, R);
    h.R = R;
    // back to the world frame: x_cam = R (X - c0) + t = R X + (t - R c0)
    h.t = cv::Vec3d(t.at<double>(0), t.at<double>(1), t.at<double>(2)) - R * cv::Vec3d(c0.x, c0.y, c0.z);
    out.push_back(std::move(h));
  }
  std::stable_sort(out.begin(), out.end(), [](const CameraHypothesis& a, const CameraHypothesis& b) {
    return a.features > b.features || (a.features == b.features && a.points > b.points);
  });
  return out;
}

cv::Mat DrawFusionFeatures(const cv::Mat& image, const FusionFeatures& f) {
  cv::Mat img;
  if (image.channels() == 1)
    cv::cvtColor(image, img, cv::COLOR_GRAY2BGR);
  else
    img = image.clone();
  cv::polylines(img, f.roi_contours, true, {0, 255, 0}, 2);
  for (const Edgelet& e : f.edgelets) {
    const unsigned h = unsigned(e.list) * 2654435761u;
    cv::line(img, e.a, e.b, cv::Scalar((h >> 8) & 255, (h >> 16) & 255, 128 + ((h >> 24) & 127)), 2);
  }
  return img;
}

}  // namespace mvkp
