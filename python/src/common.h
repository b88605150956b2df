// Shared helpers of the mvkp Python module: numpy <-> cv::Mat, options from
// keyword arguments, enums that accept their names, error translation.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <opencv2/core.hpp>

namespace mvkp::py_bindings {

namespace py = pybind11;

// ---------------------------------------------------------------- images

// What an image argument may be: 8-bit gray (H, W) or BGR (H, W, 3).
enum class ImageKind { kGray, kGrayOrBgr, kBgr };

// A cv::Mat over a numpy array's memory (no copy when the rows' pixels are
// contiguous), and the array that owns that memory. Non-contiguous pixels are
// copied (np.ascontiguousarray); (H, W, 1) is taken as (H, W). None, non-uint8
// dtypes, 4 channels and other shapes raise TypeError / ValueError naming the
// expected shape. With kGray a BGR image is converted to gray (a copy).
struct ImageArg {
  cv::Mat mat;
  py::object owner;  // keeps the memory alive while mat is used
};
ImageArg ToImage(py::handle obj, const char* what, ImageKind kind = ImageKind::kGrayOrBgr);

// A float32 (H, W) array (depth rasters): float64 and other real dtypes are
// converted; anything else raises ValueError.
ImageArg ToFloatImage(py::handle obj, const char* what);

// A numpy array owning (by a capsule) a moved-in cv::Mat: no copy of the pixels.
py::array MatToArray(cv::Mat m);
// A numpy view of memory owned by `base` (kept alive by the array).
py::array ViewOf(const cv::Mat& m, py::handle base, bool writeable = false);

py::array_t<double> Matx33ToArray(const cv::Matx33d& m);
// A target outline (4 corners) as a (4, 2) float32 array.
py::array_t<float> OutlineArray(const std::array<cv::Point2f, 4>& q);
cv::Matx33d ArrayToMatx33(py::handle obj, const char* what);

// ---------------------------------------------------------------- options

// Applies keyword arguments to an options object (a bound C++ struct): each
// key must be one of its fields (TypeError naming the valid ones otherwise);
// a dict given for a nested options field is applied to it recursively.
void ApplyKwargs(py::object& options, const py::dict& kwargs, const char* func);
// The same over several options objects: each key goes to the first that has
// it (e.g. pair(): TrainOptions then MatchOptions).
void ApplyKwargs(std::vector<py::object*> options, const py::dict& kwargs, const char* func);

// An options struct from `options` (None: defaults; an instance: copied) and kwargs.
template <class T>
T MakeOptions(py::handle options, const py::dict& kwargs, const char* func, const T& defaults = T{}) {
  if (!options.is_none() && !py::isinstance<T>(options))
    throw py::type_error(std::string(func) + "(): options must be a " +
                         py::str(py::type::of<T>().attr("__name__")).cast<std::string>() + " or None, got " +
                         py::str(py::type::of(options).attr("__name__")).cast<std::string>());
  py::object obj = options.is_none() ? py::cast(defaults) : py::cast(py::cast<T>(options));  // a copy
  ApplyKwargs(obj, kwargs, func);
  return py::cast<T>(obj);
}

// Field names of a bound options class (its properties), in definition order.
std::vector<std::string> FieldNames(py::handle cls);

// Adds __init__(**kwargs), __repr__, __eq__, copy(), to_dict() to an options class.
template <class T, class... Extra>
void AddOptionsMethods(py::class_<T, Extra...>& c) {
  c.def(py::init([](py::kwargs kw) {
          py::object obj = py::cast(T{});
          ApplyKwargs(obj, kw, py::str(py::type::of<T>().attr("__name__")).cast<std::string>().c_str());
          return py::cast<T>(obj);
        }),
        "Default options, with any field set by keyword.");
  c.def("__repr__", [](py::object self) {
    // float fields print as their float32 value's shortest form when they are float32 ("0.85").
    auto item = [](py::handle v) -> std::string {
      if (py::isinstance<py::float_>(v)) {
        const double d = v.cast<double>();
        const float f = float(d);
        if (double(f) == d && std::isfinite(d))
          for (int prec = 1; prec <= 9; ++prec) {
            char buf[32];
            std::snprintf(buf, sizeof buf, "%.*g", prec, double(f));
            if (std::strtof(buf, nullptr) == f) {
              std::string s = buf;
              if (s.find_first_of(".en") == std::string::npos) s += ".0";
              return s;
            }
          }
      }
      if (py::hasattr(py::type::of(v), "__members__")) return py::repr(py::str(v)).cast<std::string>();  // an enum: 'affine'
      return py::repr(v).cast<std::string>();
    };
    std::string s = py::str(py::type::of(self).attr("__name__")).cast<std::string>() + "(";
    bool first = true;
    for (const auto& f : FieldNames(py::type::of(self))) {
      if (!first) s += ", ";
      first = false;
      s += f + "=" + item(self.attr(f.c_str()));
    }
    return s + ")";
  });
  c.def("to_dict", [](py::object self) {
    py::dict d;
    for (const auto& f : FieldNames(py::type::of(self))) {
      py::object v = self.attr(f.c_str());
      d[f.c_str()] = py::hasattr(v, "to_dict") ? v.attr("to_dict")() : v;
    }
    return d;
  }, "The fields as a dict (nested options as dicts).");
  c.def("__eq__", [](py::object self, py::object other) {
    if (!py::type::of(self).is(py::type::of(other))) return false;
    return self.attr("to_dict")().equal(other.attr("to_dict")());
  });
  c.def("copy", [](const T& self) { return T(self); }, "A copy.");
  c.def("__copy__", [](const T& self) { return T(self); });
  c.def("__deepcopy__", [](const T& self, py::dict) { return T(self); });
  c.attr("__hash__") = py::none();
}

// An enum whose values may also be given by name ("affine" for
// GeometryModel.affine), in keyword arguments and field assignments.
template <class E, class Scope>
py::enum_<E> BindEnum(Scope& scope, const char* name, std::initializer_list<std::pair<const char*, E>> values,
                      const char* doc) {
  py::enum_<E> e(scope, name, doc);
  for (const auto& [n, v] : values) e.value(n, v);
  std::vector<std::pair<std::string, E>> table;
  for (const auto& [n, v] : values) {  // "global_" (a Python keyword) is also "global"
    std::string key = n;
    if (!key.empty() && key.back() == '_') key.pop_back();
    table.emplace_back(key, v);
  }
  const std::string ename = name;
  e.def(py::init([table, ename](const std::string& s) {
          std::string names;
          for (const auto& [n, v] : table) {
            if (n == s) return v;
            names += (names.empty() ? "" : ", ") + ("'" + n + "'");
          }
          throw py::value_error("unknown " + ename + " '" + s + "' (expected one of " + names + ")");
        }),
        py::arg("name"));
  py::delattr(e, "__str__");  // enum_'s own __str__ ("Name.value") would shadow ours as the first overload
  e.def("__str__", [table](E v) {
    for (const auto& [n, x] : table)
      if (x == v) return n;
    return std::string("?");
  });
  py::implicitly_convertible<py::str, E>();
  return e;
}

// ---------------------------------------------------------------- errors

// Registers mvkp.Error and its subclasses and the translator of mvkp::Error and
// cv::Exception into them.
void RegisterErrors(py::module_& m);

// Binding units.
void BindOptions(py::module_& m);
void BindCore(py::module_& m);
void BindRecognize(py::module_& m);
void BindIndex(py::module_& m);
void BindAerial(py::module_& m);

}  // namespace mvkp::py_bindings
