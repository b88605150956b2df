// Nearest-neighbour indexes (FFVA exact kNN, brute force), CDIKP and augmented features.
#include <memory>

#include "common.h"
#include "mvkp/augment/augment.h"
#include "mvkp/cdikp/cdikp.h"
#include "mvkp/core/error.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/knn_index.h"

namespace mvkp::py_bindings {

namespace {

struct PyIndex {
  std::unique_ptr<KnnIndex> index;
  const KnnIndex& get() const {
    if (!index) throw py::value_error("index is empty");
    return *index;
  }
};

// A float32 C-contiguous (n, dim) view of `obj`: no copy when it already is
// one (the promise the zero-copy test checks); other real dtypes and layouts
// are converted (one copy).
using FloatRows = py::array_t<float, py::array::c_style | py::array::forcecast>;
using IntRows = py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>;

FloatRows Vectors(py::handle obj, const char* what, int dim = -1) {
  if (obj.is_none()) throw py::type_error(std::string(what) + ": expected a float32 array of shape (n, dim), got None");
  py::array a = py::isinstance<py::array>(obj) ? py::reinterpret_borrow<py::array>(obj)
                                               : py::array(py::module_::import("numpy").attr("asarray")(obj));
  const char k = a.dtype().kind();
  if (k != 'f' && k != 'i' && k != 'u')
    throw py::value_error(std::string(what) + ": expected a float32 array of shape (n, dim), got dtype " +
                          py::str(a.dtype()).cast<std::string>());
  if (a.ndim() == 1 && dim > 0) a = a.attr("reshape")(1, -1);
  if (a.ndim() != 2) throw py::value_error(std::string(what) + ": expected a 2-D array of shape (n, dim), got " + std::to_string(a.ndim()) + "-D");
  if (dim > 0 && a.shape(1) != dim)
    throw py::value_error(std::string(what) + ": expected " + std::to_string(dim) + " columns (the index's dim), got " +
                          std::to_string(a.shape(1)));
  FloatRows r = FloatRows::ensure(a);  // no copy for C-contiguous float32, else one converted copy
  if (!r) throw py::error_already_set();
  return r;
}

IntRows Labels(py::handle obj, std::size_t n) {
  IntRows l;
  if (obj.is_none()) {
    l = IntRows(py::ssize_t(n));
    for (std::size_t i = 0; i < n; ++i) l.mutable_data()[i] = std::int32_t(i);
    return l;
  }
  py::array a = py::module_::import("numpy").attr("asarray")(obj);
  if (a.dtype().kind() != 'i' && a.dtype().kind() != 'u')
    throw py::value_error("labels: expected an integer array of shape (n,), got dtype " + py::str(a.dtype()).cast<std::string>());
  if (a.ndim() != 1 || std::size_t(a.shape(0)) != n)
    throw py::value_error("labels: expected shape (" + std::to_string(n) + ",), one label per vector");
  py::object np = py::module_::import("numpy");
  if (a.size() && (np.attr("any")(a.attr("__lt__")(INT32_MIN)).cast<bool>() || np.attr("any")(a.attr("__gt__")(INT32_MAX)).cast<bool>()))
    throw py::value_error("labels: values must fit in int32");
  l = IntRows::ensure(np.attr("asarray")(a, "int32"));
  if (!l) throw py::error_already_set();
  return l;
}

std::shared_ptr<PyIndex> Build(std::unique_ptr<KnnIndex> idx, py::handle data, py::handle labels) {
  auto v = Vectors(data, "data");
  if (v.shape(0) == 0) throw py::value_error("data: no vectors (shape (0, dim))");
  auto l = Labels(labels, std::size_t(v.shape(0)));
  auto out = std::make_shared<PyIndex>();
  out->index = std::move(idx);
  {
    py::gil_scoped_release release;
    out->index->Build(v.data(), std::size_t(v.shape(0)), int(v.shape(1)), l.data());
  }
  return out;
}

// Keypoints as an (n, 7) float32 array: x, y, size, angle, response, octave, class_id.
py::array_t<float> KeypointArray(const std::vector<cv::KeyPoint>& k) {
  py::array_t<float> a({py::ssize_t(k.size()), py::ssize_t(7)});
  auto v = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < k.size(); ++i) {
    v(i, 0) = k[i].pt.x;
    v(i, 1) = k[i].pt.y;
    v(i, 2) = k[i].size;
    v(i, 3) = k[i].angle;
    v(i, 4) = k[i].response;
    v(i, 5) = float(k[i].octave);
    v(i, 6) = float(k[i].class_id);
  }
  return a;
}

// From an (n, >=2) array (columns as KeypointArray; size defaults to 1, angle
// to -1) or a sequence of cv2.KeyPoint.
std::vector<cv::KeyPoint> ToKeypoints(py::handle obj) {
  if (obj.is_none()) throw py::type_error("keypoints: expected an (n, 7) float32 array or a list of cv2.KeyPoint, got None");
  std::vector<cv::KeyPoint> out;
  if (!py::isinstance<py::array>(obj) && py::isinstance<py::sequence>(obj)) {
    py::sequence s = py::reinterpret_borrow<py::sequence>(obj);
    if (s.size() == 0 || py::hasattr(s[0], "pt")) {
      for (auto k : s) {
        py::tuple pt = k.attr("pt");
        out.emplace_back(pt[0].cast<float>(), pt[1].cast<float>(), k.attr("size").cast<float>(), k.attr("angle").cast<float>(),
                         k.attr("response").cast<float>(), k.attr("octave").cast<int>(), k.attr("class_id").cast<int>());
      }
      return out;
    }
  }
  auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a || a.ndim() != 2 || a.shape(1) < 2)
    throw py::value_error("keypoints: expected an (n, 7) float32 array (x, y, size, angle, response, octave, class_id) "
                          "or a list of cv2.KeyPoint");
  const auto cols = a.shape(1);
  auto v = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    cv::KeyPoint k(v(i, 0), v(i, 1), cols > 2 ? v(i, 2) : 1.f, cols > 3 ? v(i, 3) : -1.f, cols > 4 ? v(i, 4) : 0.f,
                   cols > 5 ? int(v(i, 5)) : 0, cols > 6 ? int(v(i, 6)) : -1);
    out.push_back(k);
  }
  return out;
}

cv::Mat Codes(py::handle obj, const char* what) {
  if (obj.is_none()) throw py::type_error(std::string(what) + ": expected a uint8 or uint16 array of codes, got None");
  py::array a = py::module_::import("numpy").attr("ascontiguousarray")(obj);
  if (a.ndim() == 1) a = a.attr("reshape")(1, -1);
  if (a.ndim() != 2) throw py::value_error(std::string(what) + ": expected a 2-D array (one code per row)");
  int type;
  if (a.dtype().is(py::dtype::of<std::uint8_t>())) type = CV_8U;
  else if (a.dtype().is(py::dtype::of<std::uint16_t>())) type = CV_16U;
  else throw py::value_error(std::string(what) + ": expected dtype uint8 or uint16, got " + py::str(a.dtype()).cast<std::string>());
  // A view: callers keep `obj` alive for the call.
  return cv::Mat(int(a.shape(0)), int(a.shape(1)), type, const_cast<void*>(a.data())).clone();
}

}  // namespace

void BindIndex(py::module_& m) {
  py::class_<PyIndex, std::shared_ptr<PyIndex>>(
      m, "KnnIndex",
      "Nearest-neighbour search over labelled float32 vectors (squared L2). Make one with FfvaIndex(data), "
      "BruteForceIndex(data) or load_index(path). The index keeps its own copy of the vectors; the input array is "
      "read in place (no copy) when it is float32 and C-contiguous.")
      .def_property_readonly("size", [](const PyIndex& x) { return x.get().size(); })
      .def_property_readonly("dim", [](const PyIndex& x) { return x.get().dim(); })
      .def_property_readonly("name", [](const PyIndex& x) { return x.get().name(); })
      .def_property_readonly("memory_bytes", [](const PyIndex& x) { return x.get().memory_bytes(); })
      .def("__len__", [](const PyIndex& x) { return x.get().size(); })
      .def(
          "search",
          [](const PyIndex& x, py::handle queries, int k) {
            const KnnIndex& idx = x.get();
            if (k < 1) throw py::value_error("k must be >= 1");
            auto q = Vectors(queries, "queries", idx.dim());
            const std::size_t nq = std::size_t(q.shape(0));
            std::vector<Neighbor> out(nq * std::size_t(k));
            {
              py::gil_scoped_release release;
              if (nq) idx.SearchBatch(q.data(), nq, k, out.data());
            }
            py::array_t<float> d({py::ssize_t(nq), py::ssize_t(k)});
            py::array_t<std::int32_t> ids({py::ssize_t(nq), py::ssize_t(k)});
            for (std::size_t i = 0; i < out.size(); ++i) {
              d.mutable_data()[i] = out[i].distance;
              ids.mutable_data()[i] = out[i].id;
            }
            return py::make_tuple(d, ids);
          },
          py::arg("queries"), py::arg("k") = 1,
          "The k nearest vectors of each query, nearest first (ties: smaller id). Returns (distances, ids), both "
          "(nq, k): squared L2 float32 and int32 rows of the build data (-1 / inf when k > size). The GIL is released.")
      .def(
          "search_two_distinct",
          [](const PyIndex& x, py::handle queries, float ratio) {
            const KnnIndex& idx = x.get();
            auto q = Vectors(queries, "queries", idx.dim());
            const std::size_t nq = std::size_t(q.shape(0));
            std::vector<Neighbor> out(nq * 2);
            {
              py::gil_scoped_release release;
              if (nq) idx.SearchTwoDistinctBatch(q.data(), nq, out.data(), ratio);
            }
            py::array_t<float> d({py::ssize_t(nq), py::ssize_t(2)});
            py::array_t<std::int32_t> ids({py::ssize_t(nq), py::ssize_t(2)}), labels({py::ssize_t(nq), py::ssize_t(2)});
            for (std::size_t i = 0; i < out.size(); ++i) {
              d.mutable_data()[i] = out[i].distance;
              ids.mutable_data()[i] = out[i].id;
              labels.mutable_data()[i] = out[i].label;
            }
            return py::make_tuple(d, ids, labels);
          },
          py::arg("queries"), py::arg("ratio") = 0.f,
          "Per query the nearest vector and the nearest one with a different label (the ratio test's pair). "
          "Returns (distances, ids, labels), each (nq, 2).")
      .def("save", [](const PyIndex& x, const std::string& path) { SaveIndex(x.get(), path); }, py::arg("path"),
           "Writes an FFVA index file atomically (FFVA only).")
      .def("__repr__", [](const PyIndex& x) {
        if (!x.index) return std::string("KnnIndex(empty)");
        return "KnnIndex(" + x.index->name() + ", " + std::to_string(x.index->size()) + " x " + std::to_string(x.index->dim()) + ")";
      });

  m.def(
      "FfvaIndex",
      [](py::handle data, py::handle labels, py::handle options, py::kwargs kw) {
        const FfvaOptions o = MakeOptions<FfvaOptions>(options, kw, "FfvaIndex");
        return Build(MakeFfvaIndex(o), data, labels);
      },
      py::arg("data"), py::arg("labels") = py::none(), py::arg("options") = py::none(),
      "An FFVA index (exact kNN: results equal brute force) over data (n, dim) float32, with int32 labels (default: "
      "each vector its own). Keyword arguments are FfvaOptions fields (filter='exact', leaf_size=64, scan_blocks=8).");
  m.def(
      "BruteForceIndex", [](py::handle data, py::handle labels) { return Build(MakeBruteForceIndex(), data, labels); },
      py::arg("data"), py::arg("labels") = py::none(), "An exact linear-scan index (AVX2 when available).");
  m.def(
      "load_index",
      [](const std::string& path, py::handle options, py::kwargs kw) {
        const IndexLoadOptions o = MakeOptions<IndexLoadOptions>(options, kw, "load_index");
        auto out = std::make_shared<PyIndex>();
        py::gil_scoped_release release;
        out->index = LoadIndex(path, o);
        return out;
      },
      py::arg("path"), py::arg("options") = py::none(),
      "Loads an index file (mmap=True maps it instead of reading it). BadIndexError for corrupt files.");

  // ---------------------------------------------------------------- CDIKP
  py::class_<CDIKP, std::shared_ptr<CDIKP>>(m, "Cdikp",
                                    "CDIKP: SIFT keypoints with a 20-D Walsh-Hadamard descriptor (compare with L2). "
                                    "Keypoints are (n, 7) float32 arrays: x, y, size, angle, response, octave, class_id "
                                    "(mvkp.to_cv_keypoints() makes cv2.KeyPoint lists).")
      .def(py::init([](py::handle options, py::kwargs kw) {
             const CdikpOptions o = MakeOptions<CdikpOptions>(options, kw, "Cdikp");
             o.Check();
             return std::make_shared<CDIKP>(o);
           }),
           py::arg("options") = py::none(), "Keyword arguments are CdikpOptions fields (dims=20, patch_size=32, ...).")
      .def(
          "detect",
          [](CDIKP& self, py::handle image) {
            ImageArg img = ToImage(image, "image");
            std::vector<cv::KeyPoint> k;
            {
              py::gil_scoped_release release;
              self.detect(img.mat, k);
            }
            return KeypointArray(k);
          },
          py::arg("image"))
      .def(
          "compute",
          [](CDIKP& self, py::handle image, py::handle keypoints) {
            ImageArg img = ToImage(image, "image");
            std::vector<cv::KeyPoint> k = ToKeypoints(keypoints);
            cv::Mat d;
            {
              py::gil_scoped_release release;
              self.compute(img.mat, k, d);
            }
            if (d.empty()) d = cv::Mat(0, self.descriptorSize(), CV_32F);
            return py::make_tuple(KeypointArray(k), MatToArray(d));
          },
          py::arg("image"), py::arg("keypoints"), "Describes the given keypoints: (keypoints, descriptors (n, dims) float32).")
      .def(
          "detect_and_compute",
          [](CDIKP& self, py::handle image) {
            ImageArg img = ToImage(image, "image");
            std::vector<cv::KeyPoint> k;
            cv::Mat d;
            {
              py::gil_scoped_release release;
              self.detectAndCompute(img.mat, cv::noArray(), k, d);
            }
            if (d.empty()) d = cv::Mat(0, self.descriptorSize(), CV_32F);
            return py::make_tuple(KeypointArray(k), MatToArray(d));
          },
          py::arg("image"),
          "(keypoints (n, 7) float32, descriptors (n, dims) float32). The descriptors array owns the C++ buffer "
          "the descriptor wrote (no copy).")
      .def_property_readonly("options", &CDIKP::options)
      .def_property_readonly("descriptor_size", &CDIKP::descriptorSize)
      .def("__repr__", [](const CDIKP& c) { return "Cdikp(dims=" + std::to_string(c.options().dims) + ")"; });

  // ---------------------------------------------------------------- augment
  m.def(
      "augment",
      [](py::handle keypoints, py::handle descriptors, py::handle options, py::kwargs kw) {
        const AugmentOptions o = MakeOptions<AugmentOptions>(options, kw, "augment");
        o.Check();
        const std::vector<cv::KeyPoint> k = ToKeypoints(keypoints);
        if (descriptors.is_none()) throw py::type_error("descriptors: expected an (n, dim) float32 or uint8 array, got None");
        py::array a = py::module_::import("numpy").attr("ascontiguousarray")(descriptors);
        cv::Mat d;
        if (a.ndim() != 2) throw py::value_error("descriptors: expected an (n, dim) array");
        if (a.dtype().is(py::dtype::of<float>())) d = cv::Mat(int(a.shape(0)), int(a.shape(1)), CV_32F, const_cast<void*>(a.data()));
        else if (a.dtype().is(py::dtype::of<std::uint8_t>())) d = cv::Mat(int(a.shape(0)), int(a.shape(1)), CV_8U, const_cast<void*>(a.data()));
        else throw py::value_error("descriptors: expected dtype float32 or uint8, got " + py::str(a.dtype()).cast<std::string>());
        cv::Mat codes;
        {
          py::gil_scoped_release release;
          codes = Augment(k, d, o);
        }
        if (codes.empty()) codes = cv::Mat(0, d.cols, CV_8U);
        return MatToArray(codes);
      },
      py::arg("keypoints"), py::arg("descriptors"), py::arg("options") = py::none(),
      "Augmented features (thesis ch. 4): the ordinal code of each keypoint's sub-image, (n, dim) uint8 (uint16 "
      "when dim > 255). Keyword arguments are AugmentOptions fields (k=5, ties='local', max_tie_iterations=5).");
  m.def(
      "match_codes",
      [](py::handle codes1, py::handle codes2, AugmentMetric metric, double ratio) {
        const cv::Mat a = Codes(codes1, "codes1"), b = Codes(codes2, "codes2");
        std::vector<cv::DMatch> ms;
        {
          py::gil_scoped_release release;
          ms = MatchCodes(a, b, metric, ratio);
        }
        py::array_t<std::int32_t> idx({py::ssize_t(ms.size()), py::ssize_t(2)});
        py::array_t<float> dist(py::ssize_t(ms.size()));
        for (std::size_t i = 0; i < ms.size(); ++i) {
          idx.mutable_data()[2 * i] = ms[i].queryIdx;
          idx.mutable_data()[2 * i + 1] = ms[i].trainIdx;
          dist.mutable_data()[i] = ms[i].distance;
        }
        return py::make_tuple(idx, dist);
      },
      py::arg("codes1"), py::arg("codes2"), py::arg("metric") = AugmentMetric::kSpearman, py::arg("ratio") = 0.8,
      "Ratio-test matches of codes1 rows among codes2 rows: (pairs (m, 2) int32 [row1, row2], distances (m,) float32).");
  m.def(
      "code_similarity",
      [](py::handle a, py::handle b, AugmentMetric metric) {
        return Similarity(Codes(a, "a"), Codes(b, "b"), metric);
      },
      py::arg("a"), py::arg("b"), py::arg("metric") = AugmentMetric::kSpearman, "Similarity of two codes (1-D arrays).");
}

}  // namespace mvkp::py_bindings
