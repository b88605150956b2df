// Multi-target recognition and the target database.
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <shared_mutex>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/db/target_store.h"
#include "mvkp/model/model.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/recognize/target_db.h"
#include "mvkp/train/trainer.h"

namespace mvkp::py_bindings {

namespace {

// Recognizer with a lock: recognitions (GIL released) may run in parallel,
// add / remove wait for them (the C++ class requires that).
struct PyRecognizer {
  explicit PyRecognizer(const RecognizerOptions& o) : rec(o) {}
  Recognizer rec;
  mutable std::shared_mutex mu;
};

// TargetStore with close(): every use after close() raises ValueError.
struct PyDatabase {
  std::optional<TargetStore> store;
  std::string path;
  bool writable = false;
  TargetStore& get() {
    if (!store) throw py::value_error("mvkp.Database '" + path + "' is closed");
    return *store;
  }
};


std::string InfoRepr(const TargetInfo& i) {
  return "TargetInfo(id='" + i.id + "', title='" + i.title + "', size=" + std::to_string(i.width) + "x" +
         std::to_string(i.height) + ")";
}

// RecognizerOptions from keywords; as `mvkp recognize`, the word search has its
// own query budget (RecognizerOptions::Words(): 600 points) unless one is given.
RecognizerOptions RecOptions(py::handle options, const py::dict& kw, const char* func) {
  RecognizerOptions o = MakeOptions<RecognizerOptions>(options, kw, func);
  if (o.search == RecognizerSearch::kWords && options.is_none() && !kw.contains("match"))
    o.match.max_points = RecognizerOptions::Words().match.max_points;
  o.Check();
  return o;
}

RecognitionResult RunRecognize(const PyRecognizer& self, py::handle image, const std::string* only) {
  ImageArg img = ToImage(image, "frame", ImageKind::kGray);
  CheckImage(img.mat, "frame");
  py::gil_scoped_release release;
  std::shared_lock lock(self.mu);
  return only ? self.rec.RecognizeOne(img.mat, *only) : self.rec.Recognize(img.mat);
}

}  // namespace

void BindRecognize(py::module_& m) {
  py::class_<Recognition>(m, "Recognition", "One target found in a frame.")
      .def_readonly("id", &Recognition::id)
      .def_property_readonly("homography", [](const Recognition& r) { return Matx33ToArray(r.homography); },
                             "3x3 float64 object -> frame pixels.")
      .def_property_readonly("outline", [](const Recognition& r) { return OutlineArray(r.outline); },
                             "4x2 float32 object corners in the frame.")
      .def_readonly("inliers", &Recognition::inliers)
      .def_readonly("votes", &Recognition::votes)
      .def_readonly("score", &Recognition::score)
      .def("__repr__", [](const Recognition& r) {
        return "Recognition(id='" + r.id + "', inliers=" + std::to_string(r.inliers) + ", votes=" + std::to_string(r.votes) + ")";
      });

  py::class_<RecognitionResult>(m, "RecognitionResult", "The targets found in a frame, most inliers first.")
      .def_readonly("found", &RecognitionResult::found)
      .def_readonly("keypoints", &RecognitionResult::keypoints)
      .def_readonly("matches", &RecognitionResult::matches)
      .def_readonly("candidates", &RecognitionResult::candidates)
      .def_property_readonly("ids", [](const RecognitionResult& r) {
        std::vector<std::string> v;
        for (const auto& f : r.found) v.push_back(f.id);
        return v;
      })
      .def_property_readonly("time_ms", [](const RecognitionResult& r) {
        py::dict d;
        d["detect"] = r.detect_ms;
        d["describe"] = r.describe_ms;
        d["search"] = r.search_ms;
        d["verify"] = r.verify_ms;
        d["total"] = r.total_ms();
        return d;
      })
      .def("__len__", [](const RecognitionResult& r) { return r.found.size(); })
      .def("__iter__", [](py::object self) { return self.attr("found").attr("__iter__")(); })
      .def("__bool__", [](const RecognitionResult& r) { return !r.found.empty(); })
      .def("__repr__", [](const RecognitionResult& r) {
        std::string ids;
        for (const auto& f : r.found) ids += (ids.empty() ? "'" : ", '") + f.id + "'";
        return "RecognitionResult(found=[" + ids + "], keypoints=" + std::to_string(r.keypoints) + ")";
      });

  py::class_<PyRecognizer, std::shared_ptr<PyRecognizer>>(m, "Recognizer",
                                                         "Which of many trained targets are in a frame (mvkp::Recognizer).")
      .def(py::init([](py::handle options, py::kwargs kw) {
             const RecognizerOptions o = RecOptions(options, kw, "Recognizer");
             return std::make_shared<PyRecognizer>(o);
           }),
           py::arg("options") = py::none(),
           "Keyword arguments are RecognizerOptions fields (search='exact', max_candidates=5, min_inliers=12, "
           "match={'max_points': 1000, ...}, ...).")
      .def(
          "add",
          [](PyRecognizer& self, const std::string& id, const std::shared_ptr<Model>& model) {
            if (!model) throw py::type_error("Recognizer.add(): model is None; expected an mvkp.Model");
            py::gil_scoped_release release;
            std::unique_lock lock(self.mu);
            self.rec.Add(id, *model);
          },
          py::arg("id"), py::arg("model"), "Adds a target (InvalidArgumentError for an empty or duplicate id).")
      .def(
          "remove",
          [](PyRecognizer& self, const std::string& id) {
            py::gil_scoped_release release;
            std::unique_lock lock(self.mu);
            return self.rec.Remove(id);
          },
          py::arg("id"), "Removes a target; False if there was none.")
      .def("__contains__", [](const PyRecognizer& self, const std::string& id) {
        py::gil_scoped_release release;  // an add() in another thread may hold the lock
        std::shared_lock lock(self.mu);
        return self.rec.Contains(id);
      })
      .def("__len__", [](const PyRecognizer& self) {
        py::gil_scoped_release release;
        std::shared_lock lock(self.mu);
        return self.rec.size();
      })
      .def_property_readonly("ids", [](const PyRecognizer& self) {
        py::gil_scoped_release release;
        std::shared_lock lock(self.mu);
        return self.rec.ids();
      }, "Target ids in order of addition.")
      .def_property_readonly("options", [](const PyRecognizer& self) { return self.rec.options(); })
      .def(
          "recognize", [](const PyRecognizer& self, py::handle frame) { return RunRecognize(self, frame, nullptr); },
          py::arg("frame"), "The targets in a frame (HxW uint8 or HxWx3 BGR), most inliers first; the GIL is released.")
      .def(
          "recognize_one",
          [](const PyRecognizer& self, py::handle frame, const std::string& id) { return RunRecognize(self, frame, &id); },
          py::arg("frame"), py::arg("id"), "Looks for one target only (temporal focus).")
      .def("prepare", [](const PyRecognizer& self) {
        py::gil_scoped_release release;
        std::shared_lock lock(self.mu);
        self.rec.Prepare();
      }, "Builds the search index now instead of on the next recognize().")
      .def_property_readonly("memory_bytes", [](const PyRecognizer& self) {
        py::gil_scoped_release release;
        std::shared_lock lock(self.mu);
        return self.rec.memory_bytes();
      })
      .def("__repr__", [](const PyRecognizer& self) {
        return "Recognizer(" + std::to_string(self.rec.size()) + " targets, search=" +
               (self.rec.options().search == RecognizerSearch::kExact ? "exact" : "words") + ")";
      });

  // ---------------------------------------------------------------- database
  py::class_<TargetInfo>(m, "TargetInfo", "A target's metadata in a Database.")
      .def_readonly("id", &TargetInfo::id)
      .def_readonly("title", &TargetInfo::title)
      .def_readonly("artist", &TargetInfo::artist)
      .def_readonly("year", &TargetInfo::year)
      .def_readonly("url", &TargetInfo::url)
      .def_property_readonly("meta", [](const TargetInfo& i) { return py::module_::import("json").attr("loads")(i.meta); },
                             "The free-form metadata (a dict).")
      .def_readonly("width", &TargetInfo::width)
      .def_readonly("height", &TargetInfo::height)
      .def_readonly("added_at", &TargetInfo::added_at)
      .def("__repr__", &InfoRepr);

  py::class_<PyDatabase, std::shared_ptr<PyDatabase>>(
      m, "Database",
      "A target database (one SQLite file, as `mvkp db` makes). Database(path) opens it read-only, "
      "Database(path, writable=True) for adding and removing, Database.create(path) makes a new one. Use it as a "
      "context manager or call close(); any use after close() raises ValueError.")
      .def(py::init([](const std::string& path, bool writable) {
             auto d = std::make_shared<PyDatabase>();
             d->store.emplace(TargetStore::Open(path, writable ? TargetStore::Mode::kReadWrite : TargetStore::Mode::kReadOnly));
             d->path = path;
             d->writable = writable;
             return d;
           }),
           py::arg("path"), py::arg("writable") = false,
           "Opens an existing database (IoError if missing, BadModelError if not an mvkp database).")
      .def_static(
          "create",
          [](const std::string& path) {
            auto d = std::make_shared<PyDatabase>();
            TargetStore::Create(path);
            d->store.emplace(TargetStore::Open(path, TargetStore::Mode::kReadWrite));
            d->path = path;
            d->writable = true;
            return d;
          },
          py::arg("path"), "Creates a new, empty database and opens it for writing (IoError if the path exists).")
      .def_readonly("path", &PyDatabase::path)
      .def_property_readonly("closed", [](const PyDatabase& d) { return !d.store.has_value(); })
      .def("close", [](PyDatabase& d) { d.store.reset(); }, "Closes the file; later calls raise ValueError. Idempotent.")
      .def("__enter__", [](py::object self) { return self; })
      .def("__exit__", [](PyDatabase& d, py::args) { d.store.reset(); return false; })
      .def_property_readonly("schema_version", [](PyDatabase& d) { return d.get().schema_version(); })
      .def("__len__", [](PyDatabase& d) { return d.get().Count(); })
      .def("__contains__", [](PyDatabase& d, const std::string& id) { return d.get().Contains(id); })
      .def("ids", [](PyDatabase& d) {
        std::vector<std::string> v;
        for (const auto& i : d.get().List()) v.push_back(i.id);
        return v;
      }, "Target ids, sorted.")
      .def("list", [](PyDatabase& d) { return d.get().List(); }, "Every target's TargetInfo, ordered by id.")
      .def("info", [](PyDatabase& d, const std::string& id) { return d.get().Get(id, false).info; }, py::arg("id"),
           "One target's TargetInfo (InvalidArgumentError if absent).")
      .def(
          "model",
          [](PyDatabase& d, const std::string& id) {
            const TargetRecord r = d.get().Get(id, false);
            return std::make_shared<Model>(DeserializeModel(r.model.data(), r.model.size(), d.path + ": target '" + id + "'"));
          },
          py::arg("id"), "The target's trained Model.")
      .def(
          "backup",
          [](PyDatabase& d, const std::string& out, bool overwrite, double timeout_s) {
            d.get();  // raises if closed
            BackupOptions o;
            o.overwrite = overwrite;
            o.timeout_s = timeout_s;
            BackupReport r;
            {
              py::gil_scoped_release release;
              r = BackupTargetStore(d.path, out, o);
            }
            return r.targets;
          },
          py::arg("out"), py::kw_only(), py::arg("overwrite") = false, py::arg("timeout_s") = BackupOptions{}.timeout_s,
          "Copies the database to `out` while others may write it, as `mvkp db backup` (SQLite online backup, "
          "integrity-checked, renamed into place). Returns the number of targets copied. IoError if `out` exists "
          "(unless overwrite=True) or on a timeout.")
      .def(
          "image_bytes",
          [](PyDatabase& d, const std::string& id) {
            const TargetRecord r = d.get().Get(id, true);
            return py::bytes(reinterpret_cast<const char*>(r.image.data()), r.image.size());
          },
          py::arg("id"), "The stored encoded target image (PNG/JPEG bytes; may be empty).")
      .def(
          "add",
          [](std::shared_ptr<PyDatabase> d, const std::string& id, py::handle image, const std::string& title,
             const std::string& artist, const std::string& year, const std::string& url, py::handle meta,
             py::handle image_bytes, bool allow_duplicate, py::handle options, py::kwargs kw) {
            TargetStore& store = d->get();
            Require(d->writable, ErrorCode::kInvalidArgument, d->path + ": opened read-only (use writable=True)");
            Require(!store.Contains(id), ErrorCode::kInvalidArgument, d->path + ": target '" + id + "' already exists");
            const TrainOptions topt = MakeOptions<TrainOptions>(options, kw, "Database.add", DbTrainDefaults());
            TargetInfo info;
            info.id = id;
            info.title = title;
            info.artist = artist;
            info.year = year;
            info.url = url;
            if (!meta.is_none())
              info.meta = py::isinstance<py::str>(meta) ? meta.cast<std::string>()
                                                        : py::module_::import("json").attr("dumps")(meta).cast<std::string>();
            ValidateTargetInfo(info, /*new_id=*/true, d->path);  // before training
            ImageArg img = ToImage(image, "image");
            CheckImage(img.mat, "image");
            std::vector<std::uint8_t> bytes;
            if (!image_bytes.is_none()) {
              const std::string b = py::bytes(py::reinterpret_borrow<py::object>(image_bytes));
              bytes.assign(b.begin(), b.end());
            }
            const bool encode_png = image_bytes.is_none();
            TargetRecord r;
            {
              py::gil_scoped_release release;
              cv::Mat gray = img.mat;
              if (gray.channels() == 3) cv::cvtColor(gray, gray, cv::COLOR_BGR2GRAY);
              if (!allow_duplicate) {
                Recognizer rec;
                LoadTargets(store, rec, d->path, [](const TargetInfo&, int, int) {});
                const auto dups = FindDuplicates(rec, gray);
                Require(dups.empty(), ErrorCode::kInvalidArgument,
                        "image " + DescribeDuplicates(dups) + ", already in " + d->path +
                            ": two copies of one picture take each other's votes and neither is found "
                            "(allow_duplicate=True adds it anyway)");
              }
              if (encode_png) cv::imencode(".png", img.mat, bytes);
              r = MakeTargetRecord(info, std::move(bytes), gray, topt, "image");
            }
            d->get().Add(r);  // get() again: close() may have run meanwhile
          },
          py::arg("id"), py::arg("image"), py::kw_only(), py::arg("title") = "", py::arg("artist") = "",
          py::arg("year") = "", py::arg("url") = "", py::arg("meta") = py::none(), py::arg("image_bytes") = py::none(),
          py::arg("allow_duplicate") = false, py::arg("options") = py::none(),
          "Trains a target from `image` and adds it, as `mvkp db add` (its training defaults: max_object_side=320, "
          "other keyword arguments are TrainOptions fields). meta: a dict or JSON object text. "
          "image_bytes: the encoded image to store (default: `image` as PNG). An image that shows a target "
          "already there raises InvalidArgumentError unless allow_duplicate=True.")
      .def(
          "update",
          [](PyDatabase& d, const std::string& id, std::optional<std::string> title, std::optional<std::string> artist,
             std::optional<std::string> year, std::optional<std::string> url, py::handle meta) {
            TargetStore& store = d.get();
            Require(d.writable, ErrorCode::kInvalidArgument, d.path + ": opened read-only (use writable=True)");
            Require(store.Contains(id), ErrorCode::kInvalidArgument, d.path + ": no target '" + id + "'");
            TargetInfo info = store.Get(id, false).info;
            if (title) info.title = *title;
            if (artist) info.artist = *artist;
            if (year) info.year = *year;
            if (url) info.url = *url;
            if (!meta.is_none())
              info.meta = py::isinstance<py::str>(meta) ? meta.cast<std::string>()
                                                        : py::module_::import("json").attr("dumps")(meta).cast<std::string>();
            ValidateTargetInfo(info, /*new_id=*/false, d.path + ": target '" + id + "'");
            store.UpdateInfo(info);
            return store.Get(id, false).info;
          },
          py::arg("id"), py::kw_only(), py::arg("title") = py::none(), py::arg("artist") = py::none(),
          py::arg("year") = py::none(), py::arg("url") = py::none(), py::arg("meta") = py::none(),
          "Changes a target's metadata, as `mvkp db set` (fields left None keep their value; meta replaces the old "
          "object). Returns the new TargetInfo. The model and image stay.")
      .def("remove", [](PyDatabase& d, const std::string& id) { return d.get().Remove(id); }, py::arg("id"),
           "Removes a target; False if there was none.")
      .def(
          "recognizer",
          [](PyDatabase& d, py::handle options, py::kwargs kw) {
            const RecognizerOptions o = RecOptions(options, kw, "Database.recognizer");
            TargetStore& store = d.get();
            auto rec = std::make_shared<PyRecognizer>(o);
            LoadTargets(store, rec->rec, d.path, [](const TargetInfo&, int, int) {});
            rec->rec.ShrinkToFit();
            return rec;
          },
          py::arg("options") = py::none(),
          "A Recognizer holding every target of the database (keyword arguments: RecognizerOptions fields; "
          "search='words' uses the stored word encodings and, unless `match` is given, 600 query points as the CLI).")
      .def("__repr__", [](const PyDatabase& d) {
        if (!d.store) return "Database('" + d.path + "', closed)";
        return "Database('" + d.path + "', " + std::to_string(d.store->Count()) + " targets" + (d.writable ? ", writable" : "") + ")";
      });
}

}  // namespace mvkp::py_bindings
