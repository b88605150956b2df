// Training, models, matching, pair matching, synthetic views, target quality,
// image loading.
#include <memory>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

#include "common.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/local/local_features.h"
#include "mvkp/local/pair_match.h"
#include "mvkp/match/matcher.h"
#include "mvkp/model/model.h"
#include "mvkp/quality/quality.h"
#include "mvkp/synth/synth.h"
#include "mvkp/train/trainer.h"

namespace mvkp::py_bindings {

namespace {

std::string Fmt(double v, int prec = 2) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(prec);
  s << v;
  return s.str();
}

py::array_t<float> PointsArray(const std::vector<cv::Point2f>& p) {
  py::array_t<float> a({py::ssize_t(p.size()), py::ssize_t(2)});
  auto v = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < p.size(); ++i) {
    v(i, 0) = p[i].x;
    v(i, 1) = p[i].y;
  }
  return a;
}


// Matches of the pair matcher and of Matcher as one result type.
struct PairResult {
  std::string method;
  bool found = false;
  cv::Matx33d homography = cv::Matx33d::eye();
  std::vector<PairMatch> matches;
  int inliers = 0, keypoints1 = 0, keypoints2 = 0;
  py::dict time_ms;
};

template <class M>
py::array_t<float> CorrespondenceArray(const std::vector<M>& ms) {
  py::array_t<float> a({py::ssize_t(ms.size()), py::ssize_t(4)});
  auto v = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < ms.size(); ++i) {
    v(i, 0) = ms[i].object.x;
    v(i, 1) = ms[i].object.y;
    v(i, 2) = ms[i].query.x;
    v(i, 3) = ms[i].query.y;
  }
  return a;
}

template <class M>
py::array_t<bool> InlierArray(const std::vector<M>& ms) {
  py::array_t<bool> a(py::ssize_t(ms.size()));
  for (std::size_t i = 0; i < ms.size(); ++i) a.mutable_data()[i] = ms[i].inlier;
  return a;
}

template <class M>
py::array_t<float> DistanceArray(const std::vector<M>& ms) {
  py::array_t<float> a(py::ssize_t(ms.size()));
  for (std::size_t i = 0; i < ms.size(); ++i) a.mutable_data()[i] = ms[i].distance;
  return a;
}

py::dict TimingDict(const MatchTiming& t) {
  py::dict d;
  d["smooth"] = t.smooth_ms;
  d["detect"] = t.detect_ms;
  d["describe"] = t.describe_ms;
  d["search"] = t.search_ms;
  d["verify"] = t.verify_ms;
  d["total"] = t.total();
  return d;
}

cv::Mat GrayChecked(const ImageArg& img, const char* name) {
  CheckImage(img.mat, name);
  return img.mat;
}

Model TrainImage(py::handle image, const TrainOptions& opt) {
  ImageArg img = ToImage(image, "image", ImageKind::kGray);
  CheckImage(img.mat, "image");
  py::gil_scoped_release release;
  return Train(img.mat, opt);
}

}  // namespace

void BindCore(py::module_& m) {
  m.def("set_num_threads", [](int n) { cv::setNumThreads(n); }, py::arg("n"),
        "OpenCV worker threads used inside mvkp calls (the CLI uses 1 by default; 0 = sequential).");
  m.def("get_num_threads", [] { return cv::getNumThreads(); }, "OpenCV worker threads.");

  // ---------------------------------------------------------------- images
  m.def(
      "load_image",
      [](const std::string& path, bool color) {
        cv::Mat img;
        {
          py::gil_scoped_release release;
          img = color ? LoadImageColor(path) : LoadImageGray(path);
        }
        return MatToArray(img);
      },
      py::arg("path"), py::arg("color") = false,
      "Loads an image with mvkp's guarded decoder (as the CLI does): HxW uint8 gray, or HxWx3 BGR with color=True. "
      "Raises IoError / BadImageError naming the file.");

  m.def(
      "save_image",
      [](const std::string& path, py::handle image) {
        ImageArg img = ToImage(image, "image");
        py::gil_scoped_release release;
        SaveImage(path, img.mat);
      },
      py::arg("path"), py::arg("image"), "Writes an image (format from the extension); IoError if it cannot.");

  // ---------------------------------------------------------------- model
  py::class_<ModelParams>(m, "ModelParams", "Feature settings a model was trained with (read-only).")
      .def_readonly("smooth_sigma", &ModelParams::smooth_sigma)
      .def_readonly("patch_size", &ModelParams::patch_size)
      .def_readonly("dims", &ModelParams::dims)
      .def_readonly("orient", &ModelParams::orient)
      .def_readonly("orientation_radius", &ModelParams::orientation_radius)
      .def_readonly("min_strength", &ModelParams::min_strength)
      .def_readonly("relative_threshold", &ModelParams::relative_threshold)
      .def_readonly("min_distance", &ModelParams::min_distance)
      .def_readonly("block_size", &ModelParams::block_size)
      .def_readonly("views", &ModelParams::views)
      .def_readonly("locations", &ModelParams::locations)
      .def_readonly("clusters", &ModelParams::clusters)
      .def_readonly("seed", &ModelParams::seed)
      .def_readonly("min_scale", &ModelParams::min_scale)
      .def_readonly("max_scale", &ModelParams::max_scale)
      .def_readonly("train_ms", &ModelParams::train_ms)
      .def("__repr__", [](const ModelParams& p) {
        return "ModelParams(dims=" + std::to_string(p.dims) + ", patch_size=" + std::to_string(p.patch_size) +
               ", views=" + std::to_string(p.views) + ", locations=" + std::to_string(p.locations) +
               ", clusters=" + std::to_string(p.clusters) + ", seed=" + std::to_string(p.seed) + ")";
      });

  py::class_<Model, std::shared_ptr<Model>>(m, "Model", "A trained target (mvkp::Model). Create with train() or Model.load().")
      .def_readonly("params", &Model::params)
      .def_readonly("object_width", &Model::object_width)
      .def_readonly("object_height", &Model::object_height)
      .def_property_readonly("size", [](const Model& x) { return py::make_tuple(x.object_width, x.object_height); },
                             "(width, height) of the trained object image.")
      .def_property_readonly(
          "descriptors", [](py::object self) { return ViewOf(self.cast<const Model&>().descriptors, self); },
          "M x dims float32 k-means centres: a read-only view of the model's own memory (no copy).")
      .def_property_readonly(
          "labels",
          [](py::object self) {
            const Model& x = self.cast<const Model&>();
            py::array a(py::dtype::of<std::int32_t>(), {py::ssize_t(x.labels.size())}, {py::ssize_t(sizeof(std::int32_t))},
                        x.labels.data(), self);
            py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
            return a;
          },
          "M int32: the object location of each centre (a read-only view, no copy).")
      .def_property_readonly(
          "locations",
          [](const Model& x) {
            py::array_t<float> a({py::ssize_t(x.locations.size()), py::ssize_t(2)});
            auto v = a.mutable_unchecked<2>();
            for (std::size_t i = 0; i < x.locations.size(); ++i) {
              v(i, 0) = x.locations[i].x;
              v(i, 1) = x.locations[i].y;
            }
            return a;
          },
          "L x 2 float32 object locations (object-image pixels).")
      .def_property_readonly(
          "stability",
          [](const Model& x) {
            py::array_t<std::int32_t> a(py::ssize_t(x.locations.size()));
            for (std::size_t i = 0; i < x.locations.size(); ++i) a.mutable_data()[i] = x.locations[i].stability;
            return a;
          },
          "L int32: training views in which each location was detected.")
      .def("save", [](const Model& x, const std::string& path) { SaveModel(x, path); }, py::arg("path"),
           "Writes the model file atomically (IoError if it cannot).")
      .def_static(
          "load",
          [](const std::string& path) {
            py::gil_scoped_release release;
            return std::make_shared<Model>(LoadModel(path));
          },
          py::arg("path"), "Reads a model file (BadModelError for corrupt, truncated or newer files; IoError if missing).")
      .def("to_bytes", [](const Model& x) {
        const auto b = SerializeModel(x);
        return py::bytes(reinterpret_cast<const char*>(b.data()), b.size());
      }, "The model file's bytes.")
      .def_static(
          "from_bytes",
          [](py::bytes data, const std::string& name) {
            const std::string s = data;
            return std::make_shared<Model>(DeserializeModel(reinterpret_cast<const std::uint8_t*>(s.data()), s.size(), name));
          },
          py::arg("data"), py::arg("name") = "<bytes>", "A model from its file's bytes (BadModelError if corrupt).")
      .def("__repr__", [](const Model& x) {
        return "Model(" + std::to_string(x.object_width) + "x" + std::to_string(x.object_height) + ", " +
               std::to_string(x.locations.size()) + " locations, " + std::to_string(x.descriptors.rows) + " centres x " +
               std::to_string(x.params.dims) + " dims)";
      });
  m.attr("load_model") = m.attr("Model").attr("load");

  m.def(
      "train",
      [](py::handle image, py::handle options, py::kwargs kw) {
        const TrainOptions opt = MakeOptions<TrainOptions>(options, kw, "train");
        return std::make_shared<Model>(TrainImage(image, opt));
      },
      py::arg("image"), py::arg("options") = py::none(),
      "Trains a target model from one image (HxW uint8 gray or HxWx3 BGR). Keyword arguments are TrainOptions "
      "fields (views=100, locations=200, seed=42, ...); `options` gives a TrainOptions to start from. Raises "
      "NoTextureError when the image has too few stable points. The GIL is released while training (a `progress` "
      "callback is called with the GIL held).");

  // ---------------------------------------------------------------- matching
  py::class_<MatchResult, std::shared_ptr<MatchResult>>(m, "MatchResult", "Where a trained target is in a frame.")
      .def_readonly("found", &MatchResult::found)
      .def_property_readonly("homography",
                             [](const MatchResult& r) -> py::object {
                               if (!r.found) return py::none();
                               return Matx33ToArray(r.homography);
                             },
                             "3x3 float64 object -> frame pixels, None when not found.")
      .def_property_readonly("outline",
                             [](const MatchResult& r) -> py::object {
                               if (!r.found) return py::none();
                               return OutlineArray(r.outline);
                             },
                             "4x2 float32: object corners (0,0), (w-1,0), (w-1,h-1), (0,h-1) in the frame; None when not found.")
      .def_property_readonly("matches", [](const MatchResult& r) { return CorrespondenceArray(r.matches); },
                             "N x 4 float32 correspondences (object x, y, frame x, y) after the ratio test, before RANSAC.")
      .def_property_readonly("inlier_mask", [](const MatchResult& r) { return InlierArray(r.matches); },
                             "N bool: which matches are RANSAC inliers.")
      .def_property_readonly("distances", [](const MatchResult& r) { return DistanceArray(r.matches); },
                             "N float32 descriptor distances (L2, not squared).")
      .def_property_readonly("locations",
                             [](const MatchResult& r) {
                               py::array_t<std::int32_t> a(py::ssize_t(r.matches.size()));
                               for (std::size_t i = 0; i < r.matches.size(); ++i) a.mutable_data()[i] = r.matches[i].location;
                               return a;
                             },
                             "N int32: the model's object location of each match.")
      .def_readonly("inliers", &MatchResult::inliers)
      .def_readonly("keypoints", &MatchResult::keypoints)
      .def_readonly("final_ratio", &MatchResult::final_ratio)
      .def_property_readonly("time_ms", [](const MatchResult& r) { return TimingDict(r.time); },
                             "Per-stage milliseconds: smooth, detect, describe, search, verify, total.")
      .def("__bool__", [](const MatchResult& r) { return r.found; })
      .def("__repr__", [](const MatchResult& r) {
        return std::string("MatchResult(found=") + (r.found ? "True" : "False") + ", inliers=" + std::to_string(r.inliers) +
               ", matches=" + std::to_string(r.matches.size()) + ", keypoints=" + std::to_string(r.keypoints) + ", " +
               Fmt(r.time.total()) + " ms)";
      });

  py::class_<Matcher, std::shared_ptr<Matcher>>(m, "Matcher",
                                               "Finds one trained target in frames (mvkp::Matcher). Reuse it across frames: "
                                               "building its index costs more than a frame.")
      .def(py::init([](const std::shared_ptr<Model>& model, py::handle options, py::kwargs kw) {
             if (!model) throw py::type_error("Matcher(): model is None; expected an mvkp.Model");
             const MatchOptions opt = MakeOptions<MatchOptions>(options, kw, "Matcher");
             opt.Check();
             py::gil_scoped_release release;
             return std::make_shared<Matcher>(*model, opt);
           }),
           py::arg("model"), py::arg("options") = py::none(),
           "Keyword arguments are MatchOptions fields (max_points=500, ratio=0.85, geometry='homography', ...).")
      .def(
          "match",
          [](const Matcher& self, py::handle image) {
            ImageArg img = ToImage(image, "frame", ImageKind::kGray);
            const cv::Mat gray = GrayChecked(img, "frame");
            auto r = std::make_shared<MatchResult>();
            {
              py::gil_scoped_release release;
              *r = self.Match(gray);
            }
            return r;
          },
          py::arg("frame"), "Finds the target in a frame (HxW uint8 or HxWx3 BGR); the GIL is released meanwhile.")
      .def_property_readonly("model", [](const Matcher& x) { return std::make_shared<Model>(x.model()); }, "A copy of the model.")
      .def_property_readonly("options", [](const Matcher& x) { return x.options(); })
      .def("__repr__", [](const Matcher& x) {
        return "Matcher(" + std::to_string(x.model().object_width) + "x" + std::to_string(x.model().object_height) + " target, " +
               std::to_string(x.model().descriptors.rows) + " centres, index=" + x.options().index + ")";
      });

  // For bench_overhead.py: the same Match calls timed from C++ in this process
  // (one pass over the frames, wall ms per call), to compare with Python calls
  // under identical conditions.
  m.def(
      "_time_match_cpp",
      [](const Matcher& self, const std::vector<py::handle>& frames) {
        std::vector<cv::Mat> mats;
        std::vector<ImageArg> keep;
        for (auto f : frames) {
          keep.push_back(ToImage(f, "frame", ImageKind::kGray));
          mats.push_back(keep.back().mat);
        }
        std::vector<double> ms;
        py::gil_scoped_release release;
        for (const auto& g : mats) {
          Timer t;
          const MatchResult r = self.Match(g);
          ms.push_back(t.ElapsedMs());
        }
        return ms;
      },
      py::arg("matcher"), py::arg("frames"));

  m.def(
      "match",
      [](const std::shared_ptr<Model>& model, py::handle frame, py::handle options, py::kwargs kw) {
        if (!model) throw py::type_error("match(): model is None; expected an mvkp.Model");
        const MatchOptions opt = MakeOptions<MatchOptions>(options, kw, "match");
        opt.Check();
        ImageArg img = ToImage(frame, "frame", ImageKind::kGray);
        const cv::Mat gray = GrayChecked(img, "frame");
        auto r = std::make_shared<MatchResult>();
        py::gil_scoped_release release;
        *r = Matcher(*model, opt).Match(gray);
        return r;
      },
      py::arg("model"), py::arg("frame"), py::arg("options") = py::none(),
      "One-off: builds a Matcher and matches one frame (use Matcher for many frames).");

  m.def("project_outline", [](py::handle H, int width, int height) {
    return OutlineArray(ProjectOutline(ArrayToMatx33(H, "H"), width, height));
  }, py::arg("H"), py::arg("width"), py::arg("height"), "Where H puts the corners (0,0), (w-1,0), (w-1,h-1), (0,h-1): 4x2 float32.");
  m.def("mean_corner_error", [](py::handle a, py::handle b, int width, int height) {
    return MeanCornerError(ArrayToMatx33(a, "a"), ArrayToMatx33(b, "b"), cv::Size(width, height));
  }, py::arg("a"), py::arg("b"), py::arg("width"), py::arg("height"),
     "Mean distance (px) between where two homographies put the corners of a width x height image.");

  // ---------------------------------------------------------------- pair
  py::class_<PairResult, std::shared_ptr<PairResult>>(m, "PairResult", "Correspondences between two images.")
      .def_readonly("method", &PairResult::method)
      .def_readonly("found", &PairResult::found)
      .def_property_readonly("homography",
                             [](const PairResult& r) -> py::object {
                               if (!r.found) return py::none();
                               return Matx33ToArray(r.homography);
                             },
                             "3x3 float64 image1 -> image2 pixels, None when not found.")
      .def_property_readonly("matches", [](const PairResult& r) { return CorrespondenceArray(r.matches); },
                             "N x 4 float32 (x1, y1, x2, y2) after the ratio test.")
      .def_property_readonly("inlier_mask", [](const PairResult& r) { return InlierArray(r.matches); })
      .def_property_readonly("distances", [](const PairResult& r) { return DistanceArray(r.matches); })
      .def_readonly("inliers", &PairResult::inliers)
      .def_readonly("keypoints1", &PairResult::keypoints1)
      .def_readonly("keypoints2", &PairResult::keypoints2)
      .def_readonly("time_ms", &PairResult::time_ms)
      .def("__bool__", [](const PairResult& r) { return r.found; })
      .def("__repr__", [](const PairResult& r) {
        return "PairResult(method='" + r.method + "', found=" + (r.found ? "True" : "False") +
               ", inliers=" + std::to_string(r.inliers) + ", matches=" + std::to_string(r.matches.size()) + ")";
      });

  m.def(
      "pair",
      [](py::handle image1, py::handle image2, const std::string& method, py::kwargs kw) {
        auto out = std::make_shared<PairResult>();
        out->method = method;
        ImageArg a = ToImage(image1, "image1", ImageKind::kGray);
        ImageArg b = ToImage(image2, "image2", ImageKind::kGray);
        CheckImage(a.mat, "image1");
        CheckImage(b.mat, "image2");
        if (method == "mvkp") {
          py::object t = py::cast(TrainOptions{}), mo = py::cast(MatchOptions{});
          ApplyKwargs({&t, &mo}, kw, "pair");
          const TrainOptions topt = t.cast<TrainOptions>();
          const MatchOptions mopt = mo.cast<MatchOptions>();
          mopt.Check();
          MatchResult r;
          double train_ms = 0, total_ms = 0;
          int locations = 0;
          {
            py::gil_scoped_release release;
            Timer total;
            const Model model = Train(a.mat, topt);
            train_ms = model.params.train_ms;
            locations = int(model.locations.size());
            r = Matcher(model, mopt).Match(b.mat);
            total_ms = total.ElapsedMs();
          }
          out->found = r.found;
          out->homography = r.homography;
          out->inliers = r.inliers;
          out->keypoints1 = locations;
          out->keypoints2 = r.keypoints;
          for (const auto& c : r.matches) out->matches.push_back({c.object, c.query, c.distance, c.inlier});
          out->time_ms = TimingDict(r.time);
          out->time_ms["train"] = train_ms;
          out->time_ms["total"] = total_ms;
          return out;
        }
        py::object lo = py::cast(LocalFeatureOptions{}), po = py::cast(PairMatchOptions{});
        ApplyKwargs({&po, &lo}, kw, "pair");
        const LocalFeatureOptions lopt = lo.cast<LocalFeatureOptions>();
        const PairMatchOptions popt = po.cast<PairMatchOptions>();
        popt.Check();
        const auto impl = LocalFeatureMethod::Create(method, lopt);
        py::gil_scoped_release release;
        Timer total;
        const LocalFeatures f1 = impl->Extract(a.mat);
        const LocalFeatures f2 = impl->Extract(b.mat);
        Timer mt;
        const auto nearest = impl->Match(f1, f2);
        const double match_ms = mt.ElapsedMs();
        PairMatchResult r;
        if (!f1.keypoints.empty() && !f2.keypoints.empty()) r = MatchPair(f1, f2, nearest, popt);
        const double total_ms = total.ElapsedMs();
        py::gil_scoped_acquire acquire;
        out->found = r.found;
        out->homography = r.homography;
        out->inliers = r.inliers;
        out->matches = r.matches;
        out->keypoints1 = int(f1.keypoints.size());
        out->keypoints2 = int(f2.keypoints.size());
        out->time_ms["detect"] = f2.detect_ms;
        out->time_ms["describe"] = f2.describe_ms;
        out->time_ms["augment"] = f2.augment_ms;
        out->time_ms["search"] = match_ms;
        out->time_ms["verify"] = r.verify_ms;
        out->time_ms["total"] = total_ms;
        return out;
      },
      py::arg("image1"), py::arg("image2"), py::arg("method") = "mvkp",
      "Correspondences between two images and the homography image1 -> image2, as `mvkp pair`. method 'mvkp' trains "
      "on image1 (keywords: TrainOptions and MatchOptions fields); 'cdikp', 'sift', 'orb', 'akaze', 'aug-sift', "
      "'aug-cdikp' extract both and ratio-test (keywords: PairMatchOptions fields first, e.g. ratio=0.8, then "
      "LocalFeatureOptions fields).");
  m.def("pair_methods", [] { std::vector<std::string> v = {"mvkp"}; for (const auto& n : LocalFeatureMethodNames()) v.push_back(n); return v; },
        "Names pair() accepts as method.");

  // ---------------------------------------------------------------- synth
  m.def("prepare_target", [](py::handle target, int max_side) {
    ImageArg t = ToImage(target, "target");
    return MatToArray(PrepareTarget(t.mat, max_side));
  }, py::arg("target"), py::arg("max_side") = 320, "Resizes so the longest side is max_side (area interpolation); 0 keeps it.");
  m.def(
      "make_scene_view",
      [](py::handle target, std::uint64_t seed, py::handle background, py::handle options, py::kwargs kw) {
        const SceneOptions opt = MakeOptions<SceneOptions>(options, kw, "make_scene_view");
        opt.Check();
        ImageArg t = ToImage(target, "target");
        ImageArg bg;
        if (!background.is_none()) bg = ToImage(background, "background");
        SceneView v;
        {
          py::gil_scoped_release release;
          v = MakeSceneView(t.mat, opt, seed, bg.mat);
        }
        return py::make_tuple(MatToArray(v.image), Matx33ToArray(v.H));
      },
      py::arg("target"), py::arg("seed"), py::arg("background") = py::none(), py::arg("options") = py::none(),
      "A synthetic view of `target` (as given; see prepare_target) with clutter, lighting, blur and noise, "
      "reproducible from seed. Returns (image, H), H the 3x3 float64 target -> image homography. Keyword arguments are "
      "SceneOptions fields (width=640, height=480, perspective=0.1, ...).");
  m.def("warp", [](py::handle src, py::handle H, int width, int height, int border_value) {
    ImageArg s = ToImage(src, "src");
    const cv::Matx33d h = ArrayToMatx33(H, "H");
    cv::Mat dst;
    {
      py::gil_scoped_release release;
      WarpAntiAliased(s.mat, h, cv::Size(width, height), dst, nullptr, border_value);
    }
    return MatToArray(dst);
  }, py::arg("src"), py::arg("H"), py::arg("width"), py::arg("height"), py::arg("border_value") = 0,
     "Warps src by H (src -> dst pixels) into width x height, low-pass filtering first where H shrinks.");

  // ---------------------------------------------------------------- quality
  py::class_<QualityReport>(m, "QualityReport", "How well an image will be recognised as a target (0..100).")
      .def_readonly("score", &QualityReport::score)
      .def_readonly("verdict", &QualityReport::verdict)
      .def_readonly("detection_rate", &QualityReport::detection_rate)
      .def_readonly("test_views", &QualityReport::test_views)
      .def_readonly("median_error_px", &QualityReport::median_error_px)
      .def_readonly("eligible_tracks", &QualityReport::eligible_tracks)
      .def_readonly("train_side", &QualityReport::train_side)
      .def_readonly("selected_tracks", &QualityReport::selected_tracks)
      .def_property_readonly("factors", [](const QualityReport& r) {
        py::list l;
        for (const auto& f : r.factors) {
          py::dict d;
          d["name"] = f.name; d["value"] = f.value; d["factor"] = f.factor; d["weight"] = f.weight;
          d["points"] = f.points; d["lost"] = f.lost;
          l.append(d);
        }
        return l;
      })
      .def_property_readonly("reasons", [](const QualityReport& r) {
        py::list l;
        for (const auto& x : r.reasons) {
          py::dict d;
          d["code"] = x.code; d["message"] = x.message; d["lost"] = x.lost;
          l.append(d);
        }
        return l;
      })
      .def_property_readonly("selected", [](const QualityReport& r) {
        return PointsArray(r.selected);
      }, "N x 2 float32 selected feature positions (input pixels).")
      .def_readonly("ms", &QualityReport::ms)
      .def("__repr__", [](const QualityReport& r) {
        return "QualityReport(score=" + std::to_string(r.score) + ", verdict='" + r.verdict + "', detection_rate=" +
               Fmt(r.detection_rate, 3) + ")";
      });
  m.def(
      "assess_target",
      [](py::handle image, py::handle options, py::kwargs kw) {
        const QualityOptions opt = MakeOptions<QualityOptions>(options, kw, "assess_target");
        ImageArg img = ToImage(image, "image", ImageKind::kGray);
        py::gil_scoped_release release;
        return AssessTarget(img.mat, opt);
      },
      py::arg("image"), py::arg("options") = py::none(),
      "Target quality as `mvkp quality`: trains, matches synthetic views, scores 0..100 with reasons. Keyword "
      "arguments are QualityOptions fields (test_views=120, ...).");
}

}  // namespace mvkp::py_bindings
