// Aerial photo <-> LiDAR registration (thesis ch. 7): depth and photo
// segmentation, shape-context registration, synthetic cities. The high-level
// register_aerial() runs RegisterAerial (src/mvkp/aerial), the pipeline of `mvkp register`.
#include <algorithm>
#include <cmath>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "common.h"
#include "mvkp/aerial/aerial.h"
#include "mvkp/buildings/depth_regions.h"
#include "mvkp/city/synth_city.h"
#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/geo/raster.h"
#include "mvkp/oblique/register_view.h"
#include "mvkp/ortho/optical_regions.h"
#include "mvkp/ortho/ortho_models.h"
#include "mvkp/shapes/register.h"
#include "mvkp/shapes/edge_evidence.h"

namespace mvkp::py_bindings {

namespace {

py::array_t<std::int32_t> IntContour(const std::vector<cv::Point>& c) {
  py::array_t<std::int32_t> a({py::ssize_t(c.size()), py::ssize_t(2)});
  auto v = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < c.size(); ++i) {
    v(i, 0) = c[i].x;
    v(i, 1) = c[i].y;
  }
  return a;
}

template <class P>
py::array_t<float> FloatPoints(const std::vector<P>& c) {
  py::array_t<float> a({py::ssize_t(c.size()), py::ssize_t(2)});
  auto v = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < c.size(); ++i) {
    v(i, 0) = float(c[i].x);
    v(i, 1) = float(c[i].y);
  }
  return a;
}

// A contour from an (n, 2) array, a BuildingRegion / PhotoRegion, or anything with .contour.
Contour ToContour(py::handle obj, const std::string& what) {
  if (obj.is_none()) throw py::type_error(what + ": expected an (n, 2) array of points, got None");
  py::object o = py::reinterpret_borrow<py::object>(obj);
  if (py::hasattr(o, "contour")) o = o.attr("contour");
  auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(o);
  if (!a) throw py::type_error(what + ": expected an (n, 2) array of points");
  if (a.ndim() == 3 && a.shape(1) == 1) a = a.attr("reshape")(-1, 2);  // cv2.findContours layout
  if (a.ndim() != 2 || a.shape(1) != 2) throw py::value_error(what + ": expected an (n, 2) array of points");
  Contour c;
  for (py::ssize_t i = 0; i < a.shape(0); ++i) c.emplace_back(a.at(i, 0), a.at(i, 1));
  return c;
}

std::vector<Contour> ToContours(py::handle seq, const char* what) {
  if (seq.is_none()) throw py::type_error(std::string(what) + ": expected a list of (n, 2) point arrays, got None");
  std::vector<Contour> out;
  int i = 0;
  for (auto c : py::reinterpret_borrow<py::iterable>(seq)) out.push_back(ToContour(c, std::string(what) + "[" + std::to_string(i++) + "]"));
  return out;
}

py::array_t<int> RectTuple(const cv::Rect& r) {
  py::array_t<int> a(4);
  a.mutable_data()[0] = r.x; a.mutable_data()[1] = r.y; a.mutable_data()[2] = r.width; a.mutable_data()[3] = r.height;
  return a;
}

// A registration and what register_aerial() adds to it.
struct PyRegistration {
  Registration reg;
  std::vector<Contour> photo_regions, depth_regions;
  py::dict time_ms;
  std::string method;       // register_aerial: "regions" | "single-pair" | "outlines" | "cast-shadows" ("" when not registered)
  double confidence = 0;    // register_aerial: [0, 1] of the answer
  double photo_upscale = 1;  // register_aerial: the photo regions' segmentation size / the working size
  ShadowCompensation shadows;  // register_aerial: the cast-shadow compensation (ortho/shadows.h)
  bool shadow_fallback_used = false;  // register_aerial: the answer is the shadow fallback's
  CastShadowFit cast_shadows;        // register_aerial: the depth's shadows (aerial/cast_shadows.h)
  bool cast_shadow_fallback_used = false;
};

}  // namespace

void BindAerial(py::module_& m) {
  // ---------------------------------------------------------------- options
  py::class_<FbmModel>(m, "FbmModel", "fBm natural-texture model of the photo segmentation (invalid by default: fitted on the photo).")
      .def(py::init<>())
      .def_readwrite("k", &FbmModel::k)
      .def_readwrite("H", &FbmModel::H)
      .def_readwrite("ofe", &FbmModel::ofe)
      .def_readwrite("window", &FbmModel::window)
      .def_property_readonly("valid", &FbmModel::Valid)
      .def("__repr__", [](const FbmModel& f) {
        return "FbmModel(k=" + std::to_string(f.k) + ", H=" + std::to_string(f.H) + ", ofe=" + std::to_string(f.ofe) +
               ", window=" + std::to_string(f.window) + ")";
      });
  m.def("load_fbm_model", &LoadFbmModel, py::arg("path"), "An fBm model file from `mvkp ortho-models fit-fbm`.");
  py::class_<RegionLda>(m, "RegionLda", "Region-regulation LDA (invalid by default: the built-in one is used).")
      .def(py::init<>())
      .def_readwrite("w", &RegionLda::w)
      .def_readwrite("b", &RegionLda::b)
      .def_property_readonly("valid", &RegionLda::Valid)
      .def("__repr__", [](const RegionLda& l) { return std::string("RegionLda(") + (l.Valid() ? "valid" : "invalid: built-in") + ")"; });
  m.def("load_region_lda", &LoadRegionLda, py::arg("path"), "A region LDA file from `mvkp ortho-models train-lda`.");
  m.def("default_region_lda", &DefaultRegionLda, "The built-in region LDA.");

  py::class_<DepthSegmentOptions> dso(m, "DepthSegmentOptions", "mvkp::DepthSegmentOptions: building regions of a LiDAR depth image.");
  dso
#include "fields/DepthSegmentOptions.inc"
      ;
  AddOptionsMethods(dso);
  dso.def("check", &DepthSegmentOptions::Check);

  py::class_<OpticalSegmentOptions> oso(m, "OpticalSegmentOptions", "mvkp::OpticalSegmentOptions: roof regions of a nadir aerial photo.");
  oso
#include "fields/OpticalSegmentOptions.inc"
      ;
  AddOptionsMethods(oso);
  oso.def("check", &OpticalSegmentOptions::Check);

  py::class_<ShapeContextOptions> sco(m, "ShapeContextOptions", "mvkp::ShapeContextOptions: region shape descriptors.");
  sco
#include "fields/ShapeContextOptions.inc"
      ;
  AddOptionsMethods(sco);

  py::class_<RegistrationOptions> rgo(m, "RegistrationOptions", "mvkp::RegistrationOptions: photo <-> depth registration by region shapes.");
  BindEnum<RegistrationOptions::Model>(rgo, "Model", {{"similarity", RegistrationOptions::Model::kSimilarity}, {"affine", RegistrationOptions::Model::kAffine}, {"perspective", RegistrationOptions::Model::kPerspective}, {"auto", RegistrationOptions::Model::kAuto}}, "Global transform model.");
  rgo
#include "fields/RegistrationOptions.inc"
      ;
  AddOptionsMethods(rgo);
  rgo.def("check", &RegistrationOptions::Check);

  py::class_<EdgeEvidenceOptions> eeo(m, "EdgeEvidenceOptions",
                                      "mvkp::EdgeEvidenceOptions: the image check of a registration (depth outlines on photo edges).");
  eeo
#include "fields/EdgeEvidenceOptions.inc"
      ;
  AddOptionsMethods(eeo);
  eeo.def("check", &EdgeEvidenceOptions::Check);

  py::class_<CityOptions> cio(m, "CityOptions", "mvkp::CityOptions: a synthetic city (depth + aerial photo + ground truth).");
  cio
#include "fields/CityOptions.inc"
      ;
  AddOptionsMethods(cio);
  cio.def("check", &CityOptions::Check);

  py::class_<geo::LasRasterOptions> lro(m, "LasRasterOptions", "mvkp::geo::LasRasterOptions: rasterising a LAS point cloud.");
  lro
#include "fields/LasRasterOptions.inc"
      ;
  AddOptionsMethods(lro);
  py::class_<geo::DepthReadOptions> dro(m, "DepthReadOptions", "mvkp::geo::DepthReadOptions: reading a depth raster.");
  dro
#include "fields/DepthReadOptions.inc"
      ;
  AddOptionsMethods(dro);

  // ---------------------------------------------------------------- results
  py::class_<BuildingRegion>(m, "BuildingRegion", "A building region of a depth image.")
      .def_property_readonly("contour", [](const BuildingRegion& r) { return IntContour(r.contour); }, "(n, 2) int32 outer contour, depth px.")
      .def_property_readonly("bbox", [](const BuildingRegion& r) { return RectTuple(r.bbox); }, "(x, y, width, height).")
      .def_readonly("area", &BuildingRegion::area)
      .def_readonly("height", &BuildingRegion::height, "Median height above local ground, metres.")
      .def("__repr__", [](const BuildingRegion& r) {
        return "BuildingRegion(area=" + std::to_string(int(r.area)) + ", height=" + std::to_string(r.height) + ")";
      });
  py::class_<PhotoRegion>(m, "PhotoRegion", "A roof region of an aerial photo.")
      .def_property_readonly("contour", [](const PhotoRegion& r) { return IntContour(r.contour); }, "(n, 2) int32 outer contour, photo px.")
      .def_property_readonly("bbox", [](const PhotoRegion& r) { return RectTuple(r.bbox); }, "(x, y, width, height).")
      .def_readonly("area", &PhotoRegion::area)
      .def_readonly("confidence", &PhotoRegion::confidence)
      .def_readonly("upp", &PhotoRegion::upp)
      .def_readonly("lda_score", &PhotoRegion::lda_score)
      .def_readonly("color_preference", &PhotoRegion::color_preference)
      .def("__repr__", [](const PhotoRegion& r) {
        return "PhotoRegion(area=" + std::to_string(int(r.area)) + ", confidence=" + std::to_string(r.confidence) + ")";
      });

  py::class_<PyRegistration, std::shared_ptr<PyRegistration>>(m, "Registration", "An aerial photo registered onto a depth image.")
      .def_property_readonly("ok", [](const PyRegistration& r) { return r.reg.ok; })
      .def_property_readonly("reason", [](const PyRegistration& r) { return r.reg.reason; })
      .def_property_readonly("model", [](const PyRegistration& r) -> py::object {
        if (!r.reg.ok) return py::none();
        return py::str(r.reg.model);
      }, "'similarity' | 'affine' | 'perspective', None when not registered.")
      .def_property_readonly("homography", [](const PyRegistration& r) -> py::object {
        if (!r.reg.ok) return py::none();
        return Matx33ToArray(r.reg.photo_to_depth);
      }, "3x3 float64 photo -> depth pixels, None when not registered.")
      .def_property_readonly("correspondences", [](const PyRegistration& r) {
        py::array_t<float> a({py::ssize_t(r.reg.correspondences.size()), py::ssize_t(4)});
        auto v = a.mutable_unchecked<2>();
        for (std::size_t i = 0; i < r.reg.correspondences.size(); ++i) {
          const auto& [p, q] = r.reg.correspondences[i];
          v(i, 0) = p.x; v(i, 1) = p.y; v(i, 2) = q.x; v(i, 3) = q.y;
        }
        return a;
      }, "(n, 4) float32: photo x, y -> depth x, y.")
      .def_property_readonly("region_matches", [](const PyRegistration& r) {
        py::list l;
        for (const auto& x : r.reg.region_matches) {
          py::dict d;
          d["photo"] = x.a; d["depth"] = x.b; d["cost"] = x.cost; d["cost_ratio"] = x.cost_ratio; d["shift"] = x.shift;
          l.append(d);
        }
        return l;
      }, "Accepted region pairs: dicts of photo / depth region index, cost, cost_ratio, shift.")
      .def_property_readonly("rms_px", [](const PyRegistration& r) { return r.reg.rms_px; })
      .def_property_readonly(
          "ambiguity_px", [](const PyRegistration& r) { return r.reg.ambiguity_px; },
          "The largest mean gap, depth px, to an equally good pose the ambiguity check found (0 when it did not run).")
      .def_property_readonly(
          "relocated_px", [](const PyRegistration& r) { return r.reg.relocated_px; },
          "How far the relocation (EdgeEvidence::Relocate) moved the answer, mean depth px over the outlines in "
          "view; 0 when it kept it (EdgeEvidenceOptions.relocate_rounds = 0 and relocate_lean_gain = 0 turn it "
          "off).")
      .def_property_readonly("edge", [](const PyRegistration& r) -> py::object {
        if (!r.reg.edge.enough) return py::none();
        py::dict d;
        d["points"] = r.reg.edge.points;
        d["on"] = r.reg.edge.on;
        d["off"] = r.reg.edge.off;
        d["contrast"] = r.reg.edge.contrast;
        d["regions"] = r.reg.edge.regions;
        d["regions_on_edges"] = r.reg.edge.regions_on_edges;
        d["roof_regions"] = r.reg.edge.roof_regions;
        d["roof_contrast"] = r.reg.edge.roof_regions > 0 ? py::object(py::float_(r.reg.edge.roof_contrast)) : py::none();
        return d;
      }, "Image evidence of the result (outline samples, gradient on / beside the outlines, contrast, outlines in "
         "view and on edges, roofs scored and their median colour contrast); None when too few samples.")
      .def_property_readonly("hypotheses", [](const PyRegistration& r) { return r.reg.hypotheses; })
      .def_property_readonly("photo_regions", [](const PyRegistration& r) {
        py::list l;
        for (const auto& c : r.photo_regions) l.append(FloatPoints(c));
        return l;
      }, "Photo region contours used (photo px; (n, 2) float32 each).")
      .def_property_readonly("depth_regions", [](const PyRegistration& r) {
        py::list l;
        for (const auto& c : r.depth_regions) l.append(FloatPoints(c));
        return l;
      }, "Depth region contours used (depth px).")
      .def_readonly("time_ms", &PyRegistration::time_ms)
      .def_property_readonly("method", [](const PyRegistration& r) -> py::object {
        return r.reg.ok && !r.method.empty() ? py::object(py::str(r.method)) : py::object(py::none());
      }, "register_aerial: which method answered, 'regions', 'single-pair' (one region pair's transform vouched for by the image check) or 'outlines' (None when not registered)")
      .def_readonly("confidence", &PyRegistration::confidence, "register_aerial: confidence of the answer in [0, 1] (0 when not registered)")
      .def_readonly("photo_segmentation_upscale", &PyRegistration::photo_upscale,
                    "register_aerial: 1, or the factor a coarse photo was segmented upscaled by for the regions "
                    "of the answer (photo_min_side)")
      .def_property_readonly("shadows", [](const PyRegistration& r) {
        py::dict d;
        d["applied"] = r.shadows.applied;
        d["log_step_bgr"] = r.shadows.applied ? py::object(py::make_tuple(r.shadows.log_step[0], r.shadows.log_step[1],
                                                                          r.shadows.log_step[2]))
                                              : py::object(py::none());
        d["fraction"] = r.shadows.fraction;
        d["votes"] = r.shadows.votes;
        d["fallback_answer"] = r.shadow_fallback_used;
        return d;
      }, "register_aerial: the cast-shadow compensation: applied, the shadow step found (log B, G, R; None when "
         "not applied), the fraction of the working photo relit, the edge votes for the step, and whether the answer is "
         "the shadow fallback's")
      .def_property_readonly("cast_shadows", [](const PyRegistration& r) {
        const CastShadowFit& c = r.cast_shadows;
        py::dict d;
        d["found"] = c.found;
        d["applied"] = c.applied;
        d["fallback_answer"] = r.cast_shadow_fallback_used;
        d["reason"] = c.reason;
        d["azimuth_deg"] = c.azimuth_deg;
        d["length_depth_px_per_m"] = c.length_px_per_m;
        d["contrast"] = c.contrast;
        d["margin"] = c.margin;
        d["log_step_bgr"] = py::make_tuple(c.log_step[0], c.log_step[1], c.log_step[2]);
        d["fraction"] = c.fraction;
        return d;
      }, "register_aerial: the shadows the depth casts at a candidate pose (see cast_shadow_fallback): found (a sun stood out), applied (the photo relit), whether the answer is that "
         "pass's, the shadows' azimuth (clockwise from up in the depth) and length (depth px per metre), their "
         "darkness and margin over the other azimuths, the step (log B, G, R) and the fraction relit")
      .def_property_readonly("lean_depth_px_per_m", [](const PyRegistration& r) -> py::object {
        if (!r.reg.ok) return py::none();
        return py::make_tuple(r.reg.lean_px_per_m.x, r.reg.lean_px_per_m.y);
      }, "The photo's estimated lean (conventional orthophoto): roofs show this many depth px per metre of "
         "height from their footprints; photo_to_depth maps the ground. (0, 0) unless estimated; None when not registered.")
      .def("__bool__", [](const PyRegistration& r) { return r.reg.ok; })
      .def("__repr__", [](const PyRegistration& r) {
        if (!r.reg.ok) return "Registration(ok=False, reason='" + r.reg.reason + "')";
        return "Registration(ok=True, model='" + r.reg.model + "', region_matches=" + std::to_string(r.reg.region_matches.size()) +
               ", rms_px=" + std::to_string(r.reg.rms_px) + ")";
      });

  // ---------------------------------------------------------------- functions
  m.def(
      "segment_depth",
      [](py::handle depth, py::handle options, py::kwargs kw) {
        const DepthSegmentOptions o = MakeOptions<DepthSegmentOptions>(options, kw, "segment_depth");
        ImageArg z = ToFloatImage(depth, "depth");
        py::gil_scoped_release release;
        return SegmentDepth(cv::Mat1f(z.mat), o);
      },
      py::arg("depth"), py::arg("options") = py::none(),
      "Building regions of a depth image ((H, W) float32 metres, NaN = no data), largest first. Keyword arguments "
      "are DepthSegmentOptions fields.");
  m.def(
      "segment_optical",
      [](py::handle photo, py::handle options, py::kwargs kw) {
        const OpticalSegmentOptions o = MakeOptions<OpticalSegmentOptions>(options, kw, "segment_optical");
        ImageArg img = ToImage(photo, "photo", ImageKind::kGrayOrBgr);
        py::gil_scoped_release release;
        return SegmentOptical(img.mat, o);
      },
      py::arg("photo"), py::arg("options") = py::none(),
      "Roof regions of a nadir aerial photo (HxWx3 BGR uint8), best first. Keyword arguments are "
      "OpticalSegmentOptions fields.");
  m.def(
      "register_contours",
      [](py::handle photo_regions, py::handle depth_regions, py::handle options, py::kwargs kw) {
        const RegistrationOptions o = MakeOptions<RegistrationOptions>(options, kw, "register_contours");
        o.Check();
        auto out = std::make_shared<PyRegistration>();
        out->photo_regions = ToContours(photo_regions, "photo_regions");
        out->depth_regions = ToContours(depth_regions, "depth_regions");
        {
          py::gil_scoped_release release;
          out->reg = RegisterContours(out->photo_regions, out->depth_regions, o);
        }
        out->time_ms["match"] = out->reg.match_ms;
        out->time_ms["propagate"] = out->reg.propagate_ms;
        return out;
      },
      py::arg("photo_regions"), py::arg("depth_regions"), py::arg("options") = py::none(),
      "Registers photo region contours onto depth region contours (lists of (n, 2) arrays, or the regions "
      "segment_optical / segment_depth return). Keyword arguments are RegistrationOptions fields.");
  m.def(
      "register_aerial",
      [](py::handle depth, py::handle photo, int photo_max_side, int photo_min_side, py::handle depth_options,
         py::handle optical_options, py::handle edge_options, py::handle options, const std::string& method,
         double photo_res_m, double depth_res_m, bool shadow_compensation, bool shadow_fallback,
         bool cast_shadow_fallback, double cast_shadow_confirm_margin, int outline_roof_veto_regions,
         bool outline_objects, double outline_completeness, double outline_min_completeness, py::kwargs kw) {
        if (method != "auto" && method != "regions" && method != "outlines")
          throw py::value_error("method must be 'auto', 'regions' or 'outlines'");
        const RegistrationOptions ro = MakeOptions<RegistrationOptions>(options, kw, "register_aerial");
        ro.Check();
        const DepthSegmentOptions dso = MakeOptions<DepthSegmentOptions>(depth_options, py::dict(), "register_aerial");
        const OpticalSegmentOptions oso = MakeOptions<OpticalSegmentOptions>(optical_options, py::dict(), "register_aerial");
        if (photo_max_side < 0) throw py::value_error("photo_max_side must be >= 0");
        if (photo_min_side < 0) throw py::value_error("photo_min_side must be >= 0");
        const EdgeEvidenceOptions eo = MakeOptions<EdgeEvidenceOptions>(edge_options, py::dict(), "register_aerial");
        eo.Check();
        ImageArg z = ToFloatImage(depth, "depth");
        ImageArg img = ToImage(photo, "photo", ImageKind::kBgr);
        auto out = std::make_shared<PyRegistration>();
        double depth_ms = 0, photo_ms = 0, total_ms = 0, outline_ms = 0;
        {
          py::gil_scoped_release release;
          Timer total;
          AerialOptions ao;
          ao.photo_max_side = photo_max_side;
          ao.photo_min_side = photo_min_side;
          ao.depth = dso;
          ao.optical = oso;
          ao.edge = eo;
          ao.registration = ro;
          ao.method = method == "regions" ? AerialOptions::Method::kRegions
                      : method == "outlines" ? AerialOptions::Method::kOutlines : AerialOptions::Method::kAuto;
          ao.photo_res_m = photo_res_m;
          ao.depth_res_m = depth_res_m;
          ao.shadows.enabled = shadow_compensation;
          ao.shadow_fallback = shadow_fallback;
          ao.cast_shadow_fallback = cast_shadow_fallback;
          ao.cast_shadow_confirm_margin = cast_shadow_confirm_margin;
          ao.outline_roof_veto_regions = outline_roof_veto_regions;
          ao.outline_objects = outline_objects;
          ao.outline.completeness_power = outline_completeness;
          ao.outline.min_completeness = outline_min_completeness;
          AerialRegistration ar = RegisterAerial(cv::Mat1f(z.mat), img.mat, ao);  // the same pipeline as `mvkp register`
          out->reg = std::move(ar.registration);
          out->photo_regions = std::move(ar.photo_regions);
          out->depth_regions = std::move(ar.depth_regions);
          depth_ms = ar.segment_depth_ms;
          photo_ms = ar.segment_photo_ms;
          out->method = ar.method;
          out->confidence = out->reg.ok ? ar.confidence : 0.0;
          out->photo_upscale = ar.photo_upscale;
          out->shadows = ar.shadows;
          out->shadow_fallback_used = ar.shadow_fallback_used;
          out->cast_shadows = ar.cast_shadows;
          out->cast_shadow_fallback_used = ar.cast_shadow_fallback_used;
          outline_ms = ar.outline_search_ms;
          total_ms = total.ElapsedMs();
        }
        out->time_ms["segment_depth"] = depth_ms;
        out->time_ms["segment_photo"] = photo_ms;
        out->time_ms["match"] = out->reg.match_ms;
        out->time_ms["propagate"] = out->reg.propagate_ms;
        out->time_ms["outline_search"] = outline_ms;
        out->time_ms["total"] = total_ms;
        return out;
      },
      py::arg("depth"), py::arg("photo"), py::kw_only(), py::arg("photo_max_side") = 1200,
      py::arg("photo_min_side") = AerialOptions{}.photo_min_side,
      py::arg("depth_options") = py::none(), py::arg("optical_options") = py::none(), py::arg("edge_options") = py::none(),
      py::arg("options") = py::none(), py::arg("method") = "auto", py::arg("photo_res_m") = 0.0,
      py::arg("depth_res_m") = 0.0, py::arg("shadow_compensation") = AerialOptions{}.shadows.enabled,
      py::arg("shadow_fallback") = AerialOptions{}.shadow_fallback,
      py::arg("cast_shadow_fallback") = AerialOptions{}.cast_shadow_fallback,
      py::arg("cast_shadow_confirm_margin") = AerialOptions{}.cast_shadow_confirm_margin,
      py::arg("outline_roof_veto_regions") = AerialOptions{}.outline_roof_veto_regions,
      py::arg("outline_objects") = AerialOptions{}.outline_objects,
      py::arg("outline_completeness") = OutlineSearchOptions{}.completeness_power,
      py::arg("outline_min_completeness") = OutlineSearchOptions{}.min_completeness,
      "Registers an aerial photo (HxWx3 BGR) onto a depth image ((H, W) float32 metres) by building shapes, as "
      "`mvkp register`: segments both, matches region shapes, propagates to a global transform. 'No registration "
      "found' is a result (ok False, reason), not an error. Keyword arguments are RegistrationOptions fields "
      "(model='auto', min_regions=4, seed=1, ...); depth_options / optical_options are DepthSegmentOptions / "
      "OpticalSegmentOptions. method: 'auto' (regions, then the outline search when they find nothing), "
      "'regions' or 'outlines'; photo_res_m / depth_res_m (metres per pixel, 0 unknown) narrow the outline "
      "search's scales. photo_min_side (1200; 0 off): a smaller photo is also segmented upscaled, for when its "
      "own size finds nothing (photo_segmentation_upscale says which answered). shadow_compensation (False): "
      "blue-tinted cast shadows found in the photo are relit first; shadow_fallback (True): when the photo as "
      "it is gives no registration, a second pass on it relit, answering by region shapes only (the result's "
      "shadows says what was done); cast_shadow_fallback (True): before that, the shadows the depth casts at a "
      "refused candidate pose, when a sun stands out there, are relit and the region routes try again (the "
      "result's cast_shadows). cast_shadow_confirm_margin (0.3; 0 off): when that pass does not answer either, "
      "the candidate whose shadows stood out by this margin answers if its outlines and roofs pass the outline "
      "search's checks on the relit photo (method 'cast-shadows'; method='auto' only). outline_roof_veto_regions (2; 0: the region "
      "routes' rule): an outline-search answer whose roofs, scored over at least this many outlines, do not stand "
      "apart is refused however clear its edges. outline_objects (True): the outline search also scores the "
      "outlines of trees, hedges and sheds the depth shows (never counted as outlines in view); "
      "outline_completeness (1; 0 off): its poses' scores are weighted by the share of their building outlines' "
      "arcs on edges, to this power; outline_min_completeness (0.8; 0 off): an outline-search answer needs that "
      "share at least. "
      "The result's method and confidence say which method answered and how surely.");

  // ---------------------------------------------------------------- stage 2 (issue 22)
  py::class_<ViewRegistrar, std::shared_ptr<ViewRegistrar>>(
      m, "ViewRegistrar",
      "Stage 2 of aerial registration (issue 22): the camera of oblique views of the area of a nadir photo, "
      "through the photo's stage-1 registration (as `mvkp register-view` / `register-all`). Built once per "
      "nadir photo (trains MVKP on its tiles for method 'mvkp' and 'auto', describes its regions and edgelet "
      "lists for 'fusion' and 'auto'), then register() per view.")
      .def(py::init([](py::handle depth, py::handle nadir, py::handle nadir_to_depth, double res_m,
                       std::pair<double, double> lean, int tile_px, double nadir_gsd_m, std::vector<double> scales,
                       int min_inliers, double max_height_step_m, bool refine, bool outline_refine,
                       const std::string& method, int max_view_px) {
             ViewRegistrarOptions o;
             o.max_view_px = max_view_px;
             if (method == "mvkp") o.method = ViewMethod::kMvkp;
             else if (method == "fusion") o.method = ViewMethod::kFusion;
             else if (method == "auto") o.method = ViewMethod::kAuto;
             else throw py::value_error("method must be 'mvkp', 'fusion' or 'auto'");
             o.refine = refine;
             o.outline_refine = outline_refine;
             o.tiles.tile_px = tile_px;
             o.nadir_gsd_m = nadir_gsd_m;
             o.max_height_step_m = max_height_step_m;
             o.scales = std::move(scales);
             o.pose.min_inliers = min_inliers;
             o.Check();
             ImageArg z = ToFloatImage(depth, "depth");
             // fusion's vegetation map uses colour; MVKP converts to grey itself
             ImageArg g = ToImage(nadir, "nadir", ImageKind::kGrayOrBgr);
             const cv::Matx33d H = ArrayToMatx33(nadir_to_depth, "nadir_to_depth");
             if (!(res_m > 0)) throw py::value_error("res_m must be > 0 (metres per depth cell)");
             py::gil_scoped_release release;
             return std::make_shared<ViewRegistrar>(cv::Mat1f(z.mat), res_m, g.mat, H,
                                                    cv::Point2d(lean.first, lean.second), o);
           }),
           py::arg("depth"), py::arg("nadir"), py::arg("nadir_to_depth"), py::kw_only(), py::arg("res_m"),
           py::arg("lean") = std::pair<double, double>(0.0, 0.0), py::arg("tile_px") = 320,
           py::arg("nadir_gsd_m") = 0.4, py::arg("scales") = std::vector<double>{1.0, 0.5, 0.3},
           py::arg("min_inliers") = 15, py::arg("max_height_step_m") = 2.0, py::arg("refine") = true,
           py::arg("outline_refine") = true, py::arg("method") = "mvkp", py::arg("max_view_px") = 1600,
           "depth: (H, W) float32 DSM in metres (NaN no return); nadir: the nadir photo (gray or BGR); "
           "nadir_to_depth: stage 1's (3, 3) homography (nadir px -> depth px); res_m: metres per depth cell; "
           "lean: stage 1's lean_depth_px_per_m; max_height_step_m: pairs within a tile pixel of a larger height "
           "step of the DSM are not lifted (0: keep all); refine: refine the camera against the whole nadir photo "
           "(correlation at the corners it predicts); outline_refine: then refit it to the DSM's roof outlines seen as "
           "edges of the view, which undoes a stage-1 error; method: 'mvkp' (MVKP tiles, thesis 7.3.1), 'fusion' "
           "(regions and edgelet lists, 7.3.2) or 'auto' (mvkp, then fusion for a view mvkp finds no camera for); "
           "max_view_px: a larger view is registered resized to this (answers in its own pixels; 0: never).")
      .def(
          "register",
          [](const ViewRegistrar& reg, py::handle view, double hfov, double focal) {
            ImageArg g = ToImage(view, "view", ImageKind::kGrayOrBgr);
            const cv::Matx33d K = ViewIntrinsics(g.mat.size(), hfov, focal);
            ViewRegistration r;
            {
              py::gil_scoped_release release;
              r = reg.Register(g.mat, K);
            }
            const ViewPose& p = r.pose;
            py::dict out;
            out["ok"] = p.ok;
            out["reason"] = p.ok ? p.reason : "no registration: " + p.reason;
            out["K"] = Matx33ToArray(K);
            if (p.ok) {
              py::array_t<double> P({3, 4});
              auto v = P.mutable_unchecked<2>();
              for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 4; ++j) v(i, j) = p.camera(i, j);
              out["camera"] = P;
              out["R"] = Matx33ToArray(p.R);
              out["centre_m"] = py::make_tuple(p.centre_m[0], p.centre_m[1], p.centre_m[2]);
            } else {
              out["camera"] = py::none();
              out["R"] = py::none();
              out["centre_m"] = py::none();
            }
            py::array_t<float> M({py::ssize_t(r.matches.size()), py::ssize_t(4)});
            py::array_t<bool> inl({py::ssize_t(r.matches.size())});
            auto mv = M.mutable_unchecked<2>();
            auto iv = inl.mutable_unchecked<1>();
            for (std::size_t k = 0; k < r.matches.size(); ++k) {
              mv(k, 0) = r.matches[k].nadir.x, mv(k, 1) = r.matches[k].nadir.y;
              mv(k, 2) = r.matches[k].view.x, mv(k, 3) = r.matches[k].view.y;
              iv(k) = p.ok && p.inlier[k];
            }
            out["matches"] = M;
            out["inlier"] = inl;
            out["inliers"] = p.inliers;
            out["rms_px"] = p.rms_px;
            out["scale"] = r.scale;
            out["working_scale"] = r.working_scale;
            py::dict gr;
            gr["refined"] = r.refinement.refined;
            gr["tried"] = r.refinement.tried;
            gr["found"] = r.refinement.found;
            gr["inliers"] = r.refinement.inliers;
            gr["rms_px"] = r.refinement.rms_px;
            gr["shift_px"] = r.refinement.shift_px;
            out["refinement"] = gr;
            py::dict ol;
            ol["ran"] = r.outline.ran;
            ol["replaced"] = r.outline.replaced;
            ol["visible"] = r.outline.visible;
            ol["pairs"] = r.outline.pairs;
            ol["first_pairs"] = r.outline.first_pairs;
            ol["move_px"] = r.outline.move_px;
            out["outline_refinement"] = ol;
            out["method"] = ViewMethodName(r.method);  // the method that answered (or last tried)
            if (r.fusion_ran) {
              py::dict f;
              f["view_regions"] = r.fusion_rois;
              f["view_lists"] = r.fusion_lists;
              f["region_matches"] = r.fusion_match.region_matches;
              f["list_matches"] = r.fusion_match.list_matches;
              f["agreeing_features"] = r.fusion_features;
              f["tilt_hypothesis"] = r.fusion_tilt;
              f["hypotheses_tried"] = r.fusion_tried;
              f["ms"] = r.fusion_ms;
              out["fusion"] = f;
            } else {
              out["fusion"] = py::none();
            }
            py::dict t;
            t["match"] = r.match_ms;
            t["pose"] = r.pose_ms;
            t["refine"] = r.refine_ms;
            t["outline"] = r.outline_ms;
            out["time_ms"] = t;
            return out;
          },
          py::arg("view"), py::kw_only(), py::arg("hfov") = 50.0, py::arg("focal") = 0.0,
          "The camera of an oblique view (gray or BGR) with a pinhole of horizontal field of view hfov degrees "
          "(or focal length focal px), principal point at the centre. A dict: ok, reason, camera ((3, 4): world "
          "metres east-north-up -> view px, or None), K, R, centre_m, matches ((n, 4) nadir x, y, view x, y), "
          "inlier ((n,) bool), inliers, rms_px, scale, refinement (refined, tried, found, inliers, rms_px, "
          "shift_px), outline_refinement (ran, replaced, visible, pairs, first_pairs, move_px), method (the one "
          "that answered: 'mvkp' or 'fusion'), fusion (None when it did not run: view_regions, view_lists, "
          "region_matches, list_matches, agreeing_features, tilt_hypothesis, hypotheses_tried, ms), time_ms. "
          "'No registration' is ok False, not an error.")
      .def(
          "restage",
          [](ViewRegistrar& reg, py::handle nadir_to_depth, std::pair<double, double> lean) {
            const cv::Matx33d H = ArrayToMatx33(nadir_to_depth, "nadir_to_depth");
            py::gil_scoped_release release;
            reg.Restage(H, cv::Point2d(lean.first, lean.second));
          },
          py::arg("nadir_to_depth"), py::kw_only(), py::arg("lean") = std::pair<double, double>(0.0, 0.0),
          "Replace stage 1 (e.g. by the correction register-all reports in stage1.correction.homography), "
          "keeping the trained tiles.")
      .def_property_readonly("tiles", &ViewRegistrar::tiles, "MVKP tiles trained")
      .def_property_readonly("train_ms", &ViewRegistrar::train_ms, "training time, ms")
      .def_property_readonly("nadir_gsd_m", &ViewRegistrar::nadir_gsd_m, "metres per nadir pixel (from stage 1)")
      .def("__repr__", [](const ViewRegistrar& r) {
        return "ViewRegistrar(tiles=" + std::to_string(r.tiles()) + ", nadir_gsd_m=" + std::to_string(r.nadir_gsd_m()) +
               ")";
      });

  m.def(
      "read_depth",
      [](const std::string& path, py::handle options, py::kwargs kw) {
        const geo::DepthReadOptions o = MakeOptions<geo::DepthReadOptions>(options, kw, "read_depth");
        geo::DepthRaster d;
        {
          py::gil_scoped_release release;
          d = geo::ReadDepthRaster(path, o);
        }
        return py::make_tuple(MatToArray(d.z), d.res_m);
      },
      py::arg("path"), py::arg("options") = py::none(),
      "Reads a GeoTIFF DSM/nDSM or LAS file: (heights (H, W) float32 metres with NaN = no data, res_m).");
  m.def(
      "read_optical",
      [](const std::string& path) {
        geo::OpticalImage o;
        {
          py::gil_scoped_release release;
          o = geo::ReadOpticalImage(path);
        }
        return MatToArray(o.bgr);
      },
      py::arg("path"), "Reads an aerial image (PNG/JPEG/TIFF/GeoTIFF, ...) as HxWx3 BGR uint8.");

  // ---------------------------------------------------------------- synthetic city
  py::class_<City, std::shared_ptr<City>>(m, "City", "A synthetic city: depth raster, aerial photo and ground truth.")
      .def_property_readonly("depth", [](py::object self) { return ViewOf(self.cast<const City&>().depth, self); },
                             "(H, W) float32 DSM, metres; NaN = no return (read-only view).")
      .def_property_readonly("photo", [](py::object self) { return ViewOf(self.cast<const City&>().photo, self); },
                             "HxWx3 uint8 BGR aerial photo (read-only view).")
      .def_property_readonly("photo_to_depth", [](const City& c) { return Matx33ToArray(c.photo_to_depth); },
                             "Ground truth 3x3 float64 photo -> depth pixels.")
      .def_property_readonly("footprints", [](const City& c) {
        py::list l;
        for (const auto& f : c.footprints) l.append(FloatPoints(f));
        return l;
      }, "Building outlines in depth pixels.")
      .def_readonly("heights_m", &City::heights_m)
      .def_readonly("shapes", &City::shapes)
      .def_readonly("scale", &City::scale)
      .def_readonly("rotation_deg", &City::rotation_deg)
      .def_readonly("photo_overlap", &City::photo_overlap)
      .def_readonly("depth_overlap", &City::depth_overlap)
      .def_readonly("seed", &City::seed)
      .def("save", [](const City& c, const std::string& dir, const std::string& stem) { SaveCity(c, dir, stem); },
           py::arg("dir"), py::arg("stem") = "", "Writes depth.tif, photo.png, truth.json, ... into dir (as `mvkp synth-city`).")
      .def("__repr__", [](const City& c) {
        return "City(depth " + std::to_string(c.depth.cols) + "x" + std::to_string(c.depth.rows) + ", photo " +
               std::to_string(c.photo.cols) + "x" + std::to_string(c.photo.rows) + ", " + std::to_string(c.footprints.size()) +
               " buildings, seed=" + std::to_string(c.seed) + ")";
      });
  m.def(
      "make_city",
      [](std::uint64_t seed, py::handle options, py::kwargs kw) {
        const CityOptions o = MakeOptions<CityOptions>(options, kw, "make_city");
        o.Check();
        py::gil_scoped_release release;
        return std::make_shared<City>(MakeCity(o, seed));
      },
      py::arg("seed"), py::arg("options") = py::none(),
      "A synthetic city reproducible from (options, seed). Keyword arguments are CityOptions fields (width=1000, "
      "height=1000, buildings=30, ...).");
}

}  // namespace mvkp::py_bindings
