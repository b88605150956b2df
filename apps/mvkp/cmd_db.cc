// mvkp db: the target database (create, add, import, list, remove, export,
// backup).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "commands.h"
#include "mvkp/recognize/target_db.h"
#include "mvkp/serve/encode.h"
#include "mvkp/core/atomic_file.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/db/target_archive.h"
#include "mvkp/db/target_list.h"
#include "mvkp/db/target_store.h"
#include "mvkp/model/model.h"
#include "mvkp/train/trainer.h"
#include "output.h"

namespace mvkp::cli {
namespace {

namespace fs = std::filesystem;

struct DbArgs {
  std::string db, id, image, title, artist, year, url, meta = "{}", list, output;
  // db set: the fields given (unset ones keep their value).
  std::optional<std::string> set_title, set_artist, set_year, set_url, set_meta;
  bool json = false, force = false, keep_going = false, allow_duplicate = false;
  double timeout_s = BackupOptions{}.timeout_s;
  TrainOptions train = DbTrainDefaults();
};


using serve::InfoJson;

// The database's targets in a recogniser, to find duplicates of new images.
Recognizer LoadForDuplicates(const TargetStore& store, const std::string& db) {
  Recognizer rec;
  LoadTargets(store, rec, db, [](const TargetInfo&, int, int) {});
  return rec;
}

// Error text for an image that shows targets already there (or earlier rows).
std::string DuplicateError(const std::string& image, const std::vector<DuplicateOf>& dups) {
  return image + " " + DescribeDuplicates(dups) +
         ", already there: two copies of one picture take each other's votes and neither is found; "
         "add it anyway with --allow-duplicate";
}

int RunCreate(DbArgs& a) {
  TargetStore::Create(a.db);
  std::printf("created %s (schema %d)\n", a.db.c_str(), kTargetStoreSchemaVersion);
  return 0;
}

int RunAdd(DbArgs& a) {
  TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
  // Fail fast, before training, on what the store would refuse anyway.
  Require(!store.Contains(a.id), ErrorCode::kInvalidArgument, a.db + ": target '" + a.id + "' already exists");
  TargetInfo info;
  info.id = a.id;
  info.title = a.title;
  info.artist = a.artist;
  info.year = a.year;
  info.url = a.url;
  info.meta = a.meta;
  ValidateTargetInfo(info, /*new_id=*/true, a.db);  // before seconds of training
  const cv::Mat gray = LoadImageGray(a.image);
  if (!a.allow_duplicate) {
    const auto dups = FindDuplicates(LoadForDuplicates(store, a.db), gray);
    Require(dups.empty(), ErrorCode::kInvalidArgument, DuplicateError(a.image, dups));
  }
  Timer t;
  const TargetRecord r = MakeTargetRecord(info, ReadFileBytes(a.image), gray, a.train, a.image);
  const double train_ms = t.ElapsedMs();
  store.Add(r);
  std::printf("added '%s' (%dx%d) to %s: model %.1f KB, trained in %.0f ms, %s\n", a.id.c_str(), r.info.width,
              r.info.height, a.db.c_str(), r.model.size() / 1024.0, train_ms, Count(store.Count(), "target").c_str());
  return 0;
}

// A row of an import that failed: where (LIST:LINE, LIST: entry N, ARCHIVE:
// entry N) and why.
struct RowFailure {
  std::string where, error;
};

// Ends an import: prints each failed row (stderr), then the summary; exit 1
// if any row failed.
int ImportDone(const DbArgs& a, const TargetStore& store, std::size_t imported, std::size_t rows,
               const std::vector<RowFailure>& failed, double ms) {
  for (const auto& f : failed) std::fprintf(stderr, "mvkp db import: %s: %s\n", f.where.c_str(), f.error.c_str());
  std::printf("imported %zu of %zu targets into %s in %.1f s (%zu targets now)%s\n", imported, rows, a.db.c_str(),
              ms / 1000, store.Count(), failed.empty() ? "" : (", " + std::to_string(failed.size()) + " failed").c_str());
  return failed.empty() ? 0 : 1;
}

// An archive of `db export`: restored with its ids, metadata, added_at and
// models (nothing is retrained). The archive is read and checked before the
// database is touched; a missing database is created (and removed again if
// every entry failed).
int RunImportArchive(DbArgs& a) {
  const std::vector<ArchiveTarget> entries = ReadTargetArchive(a.list);
  std::error_code ec;
  const bool created = !fs::exists(a.db, ec);
  if (created) TargetStore::Create(a.db);
  bool keep_db = !created;
  struct Cleanup {
    const std::string& db;
    bool& keep;
    ~Cleanup() {
      std::error_code e;
      if (!keep)
        for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(db + suffix, e);
    }
  } cleanup{a.db, keep_db};
  TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
  Timer t;
  std::vector<RowFailure> failed;
  std::vector<TargetRecord> good;  // all or none (without --keep-going)
  std::size_t imported = 0;
  std::set<std::string> seen;
  for (const auto& e : entries) {
    const std::string where = a.list + ": entry " + std::to_string(e.entry) +
                              (e.record.info.id.empty() ? "" : " (id '" + e.record.info.id + "')");
    std::string error = e.error;
    if (error.empty() && !seen.insert(e.record.info.id).second) error = "the id appears twice";
    if (error.empty() && store.Contains(e.record.info.id)) error = a.db + ": target already exists";
    if (error.empty()) {
      try {
        ValidateTargetInfo(e.record.info, /*new_id=*/false, a.list);
      } catch (const Error& x) {
        error = x.what();
      }
    }
    if (!error.empty()) {
      Require(a.keep_going, ErrorCode::kInvalidArgument, where + ": " + error + " (nothing imported)");
      failed.push_back({where, error});
      continue;
    }
    if (!a.keep_going) {
      good.push_back(e.record);
      continue;
    }
    try {
      store.Restore({e.record});  // each its own transaction
      ++imported;
    } catch (const Error& x) {
      failed.push_back({where, x.what()});
    }
  }
  if (!a.keep_going) {
    store.Restore(good);
    imported = good.size();
  }
  keep_db = keep_db || imported > 0 || failed.empty();  // an empty archive restores an empty database
  return ImportDone(a, store, imported, entries.size(), failed, t.ElapsedMs());
}

// A CSV or JSON list: every row is checked (id, metadata, image file) before
// any training; then each is trained. Without --keep-going the first failing
// row stops the import, names its row and nothing is added; with it, every
// failing row is reported and the others are added.
int RunImport(DbArgs& a) {
  if (IsTargetArchive(a.list)) return RunImportArchive(a);
  TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
  // LIST.csv or LIST.json (mvkp/db/target_list.h); image paths relative to the list.
  std::vector<int> rows;
  const auto list = ReadTargetList(a.list, {}, &rows);
  Require(!list.empty(), ErrorCode::kInvalidArgument, a.list + ": no targets");
  const bool csv = fs::path(a.list).extension() != ".json" && fs::path(a.list).extension() != ".JSON";
  std::vector<RowFailure> failed;
  std::vector<bool> ok(list.size(), true);
  auto where = [&](std::size_t i) {
    return a.list + (csv ? ":" : ": entry ") + std::to_string(rows[i]) + " (id '" + list[i].first.id + "')";
  };
  auto fail = [&](std::size_t i, const std::string& error) {
    Require(a.keep_going, ErrorCode::kInvalidArgument, where(i) + ": " + error + " (nothing imported)");
    failed.push_back({where(i), error});
    ok[i] = false;
  };
  std::set<std::string> seen;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const auto& [info, image] = list[i];
    std::error_code ec;
    if (!seen.insert(info.id).second) {
      fail(i, "the id appears twice in the list");
    } else if (store.Contains(info.id)) {
      fail(i, a.db + ": target already exists");
    } else if (!fs::is_regular_file(image, ec)) {
      fail(i, image + ": no such image file");
    } else {
      try {
        ValidateTargetInfo(info, /*new_id=*/true, a.list);
      } catch (const Error& e) {
        fail(i, e.what());
      }
    }
  }
  std::vector<TargetRecord> records;
  std::vector<std::size_t> index;  // records[k] is list[index[k]]
  Timer t;
  // Duplicates of the database's targets and of earlier rows.
  Recognizer rec;
  if (!a.allow_duplicate) rec = LoadForDuplicates(store, a.db);
  for (std::size_t i = 0; i < list.size(); ++i) {
    if (!ok[i]) continue;
    try {
      const std::string& path = list[i].second;
      const cv::Mat gray = LoadImageGray(path);
      if (!a.allow_duplicate) {
        const auto dups = FindDuplicates(rec, gray);
        Require(dups.empty(), ErrorCode::kInvalidArgument, DuplicateError(path, dups));
      }
      records.push_back(MakeTargetRecord(list[i].first, ReadFileBytes(path), gray, a.train, path));
      index.push_back(i);
      if (!a.allow_duplicate) {
        const TargetRecord& r = records.back();
        rec.Add(r.info.id, DeserializeModel(r.model.data(), r.model.size(), path));
      }
    } catch (const Error& e) {
      fail(i, e.what());
    }
    // The progress bar goes to stderr (only on a terminal).
    Progress("import: target", int(i + 1), int(list.size()));
  }
  std::size_t imported = 0;
  if (!a.keep_going) {
    store.AddAll(records);  // all or none
    imported = records.size();
  } else {
    for (std::size_t k = 0; k < records.size(); ++k) {
      try {
        store.Add(records[k]);
        ++imported;
      } catch (const Error& e) {
        failed.push_back({where(index[k]), e.what()});
      }
    }
  }
  return ImportDone(a, store, imported, list.size(), failed, t.ElapsedMs());
}

int RunList(DbArgs& a) {
  const TargetStore store = TargetStore::Open(a.db);
  const auto list = store.List();
  if (a.json) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& i : list) j.push_back(InfoJson(i));
    std::cout << j.dump() << std::endl;
    return 0;
  }
  std::printf("%s: %s (schema %d)\n", a.db.c_str(), Count(list.size(), "target").c_str(), store.schema_version());
  for (const auto& i : list)
    std::printf("  %-24s %5dx%-5d %s%s%s\n", i.id.c_str(), i.width, i.height, i.title.c_str(),
                i.artist.empty() ? "" : " - ", i.artist.c_str());
  return 0;
}

// Metadata only: the model and image stay (a running server sees the change
// on its next poll of the database).
int RunSet(DbArgs& a) {
  TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
  Require(store.Contains(a.id), ErrorCode::kInvalidArgument, a.db + ": no target '" + a.id + "'");
  Require(a.set_title || a.set_artist || a.set_year || a.set_url || a.set_meta, ErrorCode::kInvalidArgument,
          "nothing to change: give --title, --artist, --year, --url or --meta");
  TargetInfo info = store.Get(a.id, /*with_image=*/false).info;
  if (a.set_title) info.title = *a.set_title;
  if (a.set_artist) info.artist = *a.set_artist;
  if (a.set_year) info.year = *a.set_year;
  if (a.set_url) info.url = *a.set_url;
  if (a.set_meta) info.meta = *a.set_meta;
  ValidateTargetInfo(info, /*new_id=*/false, a.db + ": target '" + a.id + "'");
  store.UpdateInfo(info);
  std::printf("updated '%s' in %s\n", a.id.c_str(), a.db.c_str());
  return 0;
}

int RunRemove(DbArgs& a) {
  TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
  Require(store.Remove(a.id), ErrorCode::kInvalidArgument, a.db + ": no target '" + a.id + "'");
  std::printf("removed '%s' from %s (%s left)\n", a.id.c_str(), a.db.c_str(), Count(store.Count(), "target").c_str());
  return 0;
}

int RunExport(DbArgs& a) {
  if (!a.output.empty()) {
    Timer t;
    const std::size_t n = ExportTargetArchive(a.db, a.output, a.force);
    std::printf("exported %zu targets (metadata, images, models) to %s in %.1f s\n", n, a.output.c_str(),
                t.ElapsedMs() / 1000);
    return 0;
  }
  // No OUT: the metadata as JSON on stdout (not a backup).
  const TargetStore store = TargetStore::Open(a.db);
  nlohmann::json j = {{"database", a.db}, {"schema", store.schema_version()}, {"targets", nlohmann::json::array()}};
  for (const auto& i : store.List()) j["targets"].push_back(InfoJson(i));
  std::cout << j.dump(1) << std::endl;
  return 0;
}

int RunBackup(DbArgs& a) {
  BackupOptions o;
  o.overwrite = a.force;
  o.timeout_s = a.timeout_s;
  Timer t;
  const BackupReport r = BackupTargetStore(a.db, a.output, o);
  std::printf("backed up %s to %s: %zu targets, %zu pages, integrity ok, %.1f s\n", a.db.c_str(), a.output.c_str(),
              r.targets, r.pages, t.ElapsedMs() / 1000);
  return 0;
}

}  // namespace

void RegisterDb(CLI::App& app, int* code) {
  auto* db = app.add_subcommand("db", "Target database: create, add, import, list, set, remove, export, backup");
  db->require_subcommand(1);
  auto a = std::make_shared<DbArgs>();
  auto* c = db->add_subcommand("create", "Create an empty target database");
  c->add_option("DB", a->db, "database file to create")->required();
  c->callback([a, code] { *code = RunCreate(*a); });

  auto* add = db->add_subcommand("add", "Train a target from an image and add it (one transaction)");
  add->add_option("DB", a->db, "database file")->required();
  add->add_option("--id", a->id, "target id (unique)")->required();
  add->add_option("--image", a->image, "target image")->required();
  add->add_option("--title", a->title, "title");
  add->add_option("--artist", a->artist, "artist");
  add->add_option("--year", a->year, "year");
  add->add_option("--url", a->url, "link to more information");
  add->add_option("--meta", a->meta, "free-form JSON object")->capture_default_str();
  add->add_flag("--allow-duplicate", a->allow_duplicate,
                 "add it even if it shows a target already there (both then go unrecognised)");
  AddTrainOptions(add, &a->train);
  add->callback([a, code] { *code = RunAdd(*a); });

  auto* imp = db->add_subcommand(
      "import", "Train and add every target of a CSV or JSON list, or restore an export archive (all or none)");
  imp->add_option("DB", a->db, "database file (created for an archive if missing)")->required();
  imp->add_option("LIST", a->list, "LIST.csv (id,image,title,artist,year,url,meta), LIST.json or ARCHIVE.tar")
      ->required();
  imp->add_flag("--keep-going", a->keep_going,
                "import the rows that work, report every failing row (exit 1 if any failed)");
  imp->add_flag("--allow-duplicate", a->allow_duplicate,
                "import rows that show a target already there or an earlier row's");
  AddTrainOptions(imp, &a->train);
  imp->callback([a, code] { *code = RunImport(*a); });

  auto* list = db->add_subcommand("list", "List the targets");
  list->add_option("DB", a->db, "database file")->required();
  list->add_flag("--json", a->json, "a JSON array");
  list->callback([a, code] { *code = RunList(*a); });

  auto* set = db->add_subcommand("set", "Change a target's title, artist, year, link or meta (not its image)");
  set->add_option("DB", a->db, "database file")->required();
  set->add_option("ID", a->id, "target id")->required();
  set->add_option("--title", a->set_title, "new title");
  set->add_option("--artist", a->set_artist, "new artist");
  set->add_option("--year", a->set_year, "new year");
  set->add_option("--url", a->set_url, "new link (http(s)://)");
  set->add_option("--meta", a->set_meta, "new free-form JSON object (replaces the old)");
  set->callback([a, code] { *code = RunSet(*a); });

  auto* rm = db->add_subcommand("remove", "Remove a target (one transaction)");
  rm->add_option("DB", a->db, "database file")->required();
  rm->add_option("ID", a->id, "target id")->required();
  rm->callback([a, code] { *code = RunRemove(*a); });

  auto* ex = db->add_subcommand(
      "export", "Write an archive (tar: metadata, images, models) that `db import` restores; without OUT, print the metadata");
  ex->add_option("DB", a->db, "database file")->required();
  ex->add_option("OUT,-o,--output", a->output, "archive to write (e.g. museum.tar)");
  ex->add_flag("--force", a->force, "replace an existing OUT");
  ex->callback([a, code] { *code = RunExport(*a); });

  auto* bk = db->add_subcommand("backup", "Copy a live database consistently (SQLite online backup), integrity-checked");
  bk->add_option("DB", a->db, "database file (a server may be writing it)")->required();
  bk->add_option("OUT", a->output, "copy to write")->required();
  bk->add_flag("--force", a->force, "replace an existing OUT");
  bk->add_option("--timeout", a->timeout_s, "give up after this many seconds")->capture_default_str()->check(
      CLI::PositiveNumber);
  bk->callback([a, code] { *code = RunBackup(*a); });
}

}  // namespace mvkp::cli
