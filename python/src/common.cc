#include "common.h"

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp::py_bindings {

namespace {

std::string ShapeStr(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  if (a.ndim() == 1) s += ",";
  return s + ")";
}

std::string Describe(const py::array& a) {
  return py::str(a.dtype()).cast<std::string>() + " array of shape " + ShapeStr(a);
}

py::array AsArray(py::handle obj, const std::string& what, const std::string& expected) {
  if (obj.is_none()) throw py::type_error(what + ": expected " + expected + ", got None");
  if (py::isinstance<py::array>(obj)) return py::reinterpret_borrow<py::array>(obj);
  try {
    return py::module_::import("numpy").attr("asarray")(obj);
  } catch (py::error_already_set&) {
    throw py::type_error(what + ": expected " + expected + ", got " +
                         py::str(py::type::of(obj).attr("__name__")).cast<std::string>());
  }
}

}  // namespace

ImageArg ToImage(py::handle obj, const char* what_c, ImageKind kind) {
  const std::string what = what_c;
  const std::string expected = kind == ImageKind::kBgr ? "a uint8 numpy array of shape (H, W, 3) (BGR) or (H, W)"
                                                       : "a uint8 numpy array of shape (H, W) or (H, W, 3) (BGR)";
  py::array a = AsArray(obj, what, expected);
  if (a.dtype().kind() == 'O' || a.ndim() == 0)
    throw py::type_error(what + ": expected " + expected + ", got " + Describe(a));
  if (!a.dtype().is(py::dtype::of<std::uint8_t>()))
    throw py::value_error(what + ": expected " + expected + ", got " + Describe(a) +
                          (a.dtype().kind() == 'f' ? " (convert with (img * 255).clip(0, 255).astype(np.uint8) if it "
                                                     "is in [0, 1], or img.astype(np.uint8) if in [0, 255])"
                                                   : ""));
  int channels = 1;
  if (a.ndim() == 3) {
    channels = int(a.shape(2));
    if (channels == 4)
      throw py::value_error(what + ": expected " + expected + ", got a 4-channel image " + ShapeStr(a) +
                            " (drop alpha first, e.g. cv2.cvtColor(img, cv2.COLOR_BGRA2BGR))");
    if (channels != 1 && channels != 3)
      throw py::value_error(what + ": expected " + expected + ", got " + Describe(a));
  } else if (a.ndim() != 2) {
    throw py::value_error(what + ": expected " + expected + ", got " + Describe(a));
  }
  if (a.shape(0) == 0 || a.shape(1) == 0)
    throw py::value_error(what + ": empty image " + ShapeStr(a) + "; expected " + expected);
  // Zero-copy when each row's pixels are contiguous (row padding, e.g. a
  // column crop, is fine); otherwise one contiguous copy.
  const bool rows_ok = a.strides(0) > 0 && (a.ndim() == 2 ? a.strides(1) == 1 : a.strides(1) == channels && a.strides(2) == 1) &&
                       a.strides(0) >= a.shape(1) * channels;
  if (!rows_ok) a = py::module_::import("numpy").attr("ascontiguousarray")(a);
  ImageArg r;
  r.mat = cv::Mat(int(a.shape(0)), int(a.shape(1)), CV_8UC(channels), const_cast<void*>(a.data()), std::size_t(a.strides(0)));
  r.owner = a;
  if (channels == 3 && kind == ImageKind::kGray) {
    cv::Mat g;
    cv::cvtColor(r.mat, g, cv::COLOR_BGR2GRAY);
    r.mat = g;
    r.owner = py::none();
  } else if (channels == 1 && kind == ImageKind::kBgr) {
    cv::Mat c;
    cv::cvtColor(r.mat, c, cv::COLOR_GRAY2BGR);
    r.mat = c;
    r.owner = py::none();
  }
  return r;
}

ImageArg ToFloatImage(py::handle obj, const char* what_c) {
  const std::string what = what_c;
  const std::string expected = "a float32 numpy array of shape (H, W) (heights, NaN = no data)";
  py::array a = AsArray(obj, what, expected);
  if (a.ndim() != 2 || !(a.dtype().kind() == 'f' || a.dtype().kind() == 'i' || a.dtype().kind() == 'u'))
    throw py::value_error(what + ": expected " + expected + ", got " + Describe(a));
  if (a.shape(0) == 0 || a.shape(1) == 0) throw py::value_error(what + ": empty image " + ShapeStr(a));
  py::array_t<float, py::array::c_style | py::array::forcecast> f(a);  // no copy for C-contiguous float32
  ImageArg r;
  r.mat = cv::Mat(int(f.shape(0)), int(f.shape(1)), CV_32F, const_cast<float*>(f.data()));
  r.owner = f;
  return r;
}

py::array MatToArray(cv::Mat m) {
  if (!m.isContinuous()) m = m.clone();
  auto* owned = new cv::Mat(std::move(m));
  py::capsule cap(owned, [](void* p) { delete static_cast<cv::Mat*>(p); });
  return ViewOf(*owned, cap, true);
}

py::array ViewOf(const cv::Mat& m, py::handle base, bool writeable) {
  py::dtype dt;
  switch (m.depth()) {
    case CV_8U: dt = py::dtype::of<std::uint8_t>(); break;
    case CV_16U: dt = py::dtype::of<std::uint16_t>(); break;
    case CV_32S: dt = py::dtype::of<std::int32_t>(); break;
    case CV_32F: dt = py::dtype::of<float>(); break;
    case CV_64F: dt = py::dtype::of<double>(); break;
    default: throw std::runtime_error("unsupported cv::Mat depth");
  }
  std::vector<py::ssize_t> shape = {m.rows, m.cols}, strides = {py::ssize_t(m.step[0]), py::ssize_t(m.elemSize())};
  if (m.channels() > 1) {
    shape.push_back(m.channels());
    strides.push_back(py::ssize_t(m.elemSize1()));
  }
  py::array a(dt, shape, strides, m.data, base);
  if (!writeable) py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return a;
}

py::array_t<double> Matx33ToArray(const cv::Matx33d& m) {
  py::array_t<double> a({3, 3});
  auto v = a.mutable_unchecked<2>();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) v(r, c) = m(r, c);
  return a;
}

cv::Matx33d ArrayToMatx33(py::handle obj, const char* what) {
  py::array a = AsArray(obj, what, "a 3x3 float array");
  if (a.ndim() != 2 || a.shape(0) != 3 || a.shape(1) != 3)
    throw py::value_error(std::string(what) + ": expected a (3, 3) array, got " + Describe(a));
  py::array_t<double, py::array::c_style | py::array::forcecast> d(a);
  cv::Matx33d m;
  for (int i = 0; i < 9; ++i) m.val[i] = d.data()[i];
  return m;
}

// ---------------------------------------------------------------- options

std::vector<std::string> FieldNames(py::handle cls) {
  std::vector<std::string> out;
  py::object property = py::module_::import("builtins").attr("property");
  py::dict d = cls.attr("__dict__");
  for (auto item : d) {
    const std::string k = py::str(item.first);
    if (k.empty() || k[0] == '_') continue;
    if (py::isinstance(item.second, property)) out.push_back(k);
  }
  return out;
}

namespace {

bool IsOptions(py::handle v) { return py::hasattr(v, "to_dict") && py::hasattr(py::type::of(v), "__dict__"); }

void SetField(py::object& options, const std::string& key, py::handle value, const char* func) {
  py::object current = options.attr(key.c_str());
  if (py::isinstance<py::dict>(value) && IsOptions(current)) {
    ApplyKwargs(current, py::reinterpret_borrow<py::dict>(value), func);
    options.attr(key.c_str()) = current;  // def_readwrite returned a reference, but be explicit
    return;
  }
  // An enum field given by name: construct it here so a bad name reports the valid ones.
  if (py::isinstance<py::str>(value) && py::hasattr(py::type::of(current), "__members__")) {
    try {
      options.attr(key.c_str()) = py::type::of(current)(value);
    } catch (py::error_already_set& e) {
      if (!e.matches(PyExc_ValueError)) throw;
      throw py::value_error(std::string(func) + "(): " + key + ": " + py::str(e.value()).cast<std::string>());
    }
    return;
  }
  try {
    options.attr(key.c_str()) = value;
  } catch (py::error_already_set& e) {
    if (e.matches(PyExc_ValueError)) throw py::value_error(std::string(func) + "(): " + key + ": " + py::str(e.value()).cast<std::string>());
    if (!e.matches(PyExc_TypeError)) throw;
    const std::string type = py::str(py::type::of(current).attr("__name__"));
    throw py::type_error(std::string(func) + "(): option '" + key + "' expects " + type + ", got " +
                         py::repr(value).cast<std::string>());
  }
}

}  // namespace

void ApplyKwargs(std::vector<py::object*> options, const py::dict& kwargs, const char* func) {
  for (auto item : kwargs) {
    const std::string key = py::str(item.first);
    bool done = false;
    for (py::object* o : options) {
      const auto names = FieldNames(py::type::of(*o));
      if (std::find(names.begin(), names.end(), key) != names.end()) {
        SetField(*o, key, item.second, func);
        done = true;
        break;
      }
    }
    if (!done) {
      std::string valid;
      for (py::object* o : options)
        for (const auto& n : FieldNames(py::type::of(*o))) valid += (valid.empty() ? "" : ", ") + n;
      throw py::type_error(std::string(func) + "() got an unexpected keyword argument '" + key + "' (options: " + valid + ")");
    }
  }
}

void ApplyKwargs(py::object& options, const py::dict& kwargs, const char* func) { ApplyKwargs(std::vector<py::object*>{&options}, kwargs, func); }

// ---------------------------------------------------------------- errors

void RegisterErrors(py::module_& m) {
  py::object builtins = py::module_::import("builtins");
  py::object type = builtins.attr("type");
  auto make = [&](const char* name, py::tuple bases, const char* doc) {
    py::dict ns;
    ns["__module__"] = "mvkp";
    ns["__doc__"] = doc;
    py::object cls = type(name, bases, ns);
    m.attr(name) = cls;
    return cls;
  };
  py::object base = make("Error", py::make_tuple(builtins.attr("RuntimeError")),
                         "Base class of the errors mvkp reports; `code` names the C++ mvkp::ErrorCode.");
  static py::object invalid = make("InvalidArgumentError", py::make_tuple(base, builtins.attr("ValueError")),
                                   "An option or argument is out of range (ErrorCode::kInvalidArgument).");
  static py::object io = make("IoError", py::make_tuple(base, builtins.attr("OSError")),
                              "A file is missing, unreadable or cannot be written (ErrorCode::kIo).");
  static py::object bad_image = make("BadImageError", py::make_tuple(base, builtins.attr("ValueError")),
                                     "Not an image, truncated, empty, too small or too large (ErrorCode::kBadImage).");
  static py::object bad_model = make("BadModelError", py::make_tuple(base),
                                     "A model file (or database) is corrupt, truncated or of another version (ErrorCode::kBadModel).");
  static py::object no_texture = make("NoTextureError", py::make_tuple(base),
                                      "A target has too little texture to train on (ErrorCode::kNoTexture).");
  static py::object bad_index = make("BadIndexError", py::make_tuple(base),
                                     "An index or vector file is corrupt, truncated or of another version (ErrorCode::kBadIndex).");
  static py::object base_s = base;
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const mvkp::Error& e) {
      py::object cls;
      const char* code = "";
      switch (e.code()) {
        case ErrorCode::kInvalidArgument: cls = invalid; code = "invalid_argument"; break;
        case ErrorCode::kIo: cls = io; code = "io"; break;
        case ErrorCode::kBadImage: cls = bad_image; code = "bad_image"; break;
        case ErrorCode::kBadModel: cls = bad_model; code = "bad_model"; break;
        case ErrorCode::kNoTexture: cls = no_texture; code = "no_texture"; break;
        case ErrorCode::kBadIndex: cls = bad_index; code = "bad_index"; break;
        default: cls = base_s; code = "unknown"; break;
      }
      py::object exc = cls(e.what());
      exc.attr("code") = code;
      PyErr_SetObject(cls.ptr(), exc.ptr());
    } catch (const cv::Exception& e) {
      PyErr_SetString(PyExc_RuntimeError, ("OpenCV error: " + e.err).c_str());
    }
  });
}

py::array_t<float> OutlineArray(const std::array<cv::Point2f, 4>& q) {
  py::array_t<float> a({4, 2});
  auto v = a.mutable_unchecked<2>();
  for (int i = 0; i < 4; ++i) {
    v(i, 0) = q[std::size_t(i)].x;
    v(i, 1) = q[std::size_t(i)].y;
  }
  return a;
}

}  // namespace mvkp::py_bindings
