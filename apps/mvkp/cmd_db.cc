// mvkp db: the target database (create, add, import, list, remove, export).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <map>
#include <set>
#include <sstream>

#include "commands.h"
#include "mvkp/recognize/target_db.h"
#include "mvkp/serve/encode.h"
#include "mvkp/core/atomic_file.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
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
  bool json = false;
  TrainOptions train = DbTrainDefaults();
};

// Trains one target and packs it as a store record.
TargetRecord MakeRecord(TargetInfo info, const std::string& image_path, const TrainOptions& train) {
  return MakeTargetRecord(std::move(info), ReadFileBytes(image_path), LoadImageGray(image_path), train, image_path);
}

using serve::InfoJson;

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
  Timer t;
  const TargetRecord r = MakeRecord(info, a.image, a.train);
  const double train_ms = t.ElapsedMs();
  store.Add(r);
  std::printf("added '%s' (%dx%d) to %s: model %.1f KB, trained in %.0f ms, %zu targets\n", a.id.c_str(), r.info.width,
              r.info.height, a.db.c_str(), r.model.size() / 1024.0, train_ms, store.Count());
  return 0;
}

int RunImport(DbArgs& a) {
  TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
  // LIST.csv or LIST.json (mvkp/db/target_list.h); image paths relative to the list.
  const auto list = ReadTargetList(a.list);
  Require(!list.empty(), ErrorCode::kInvalidArgument, a.list + ": no targets");
  std::set<std::string> seen;
  for (const auto& [info, image] : list) {
    Require(seen.insert(info.id).second, ErrorCode::kInvalidArgument, a.list + ": id '" + info.id + "' appears twice");
    Require(!store.Contains(info.id), ErrorCode::kInvalidArgument, a.db + ": target '" + info.id + "' already exists");
  }
  std::vector<TargetRecord> records;
  Timer t;
  for (std::size_t i = 0; i < list.size(); ++i) {
    records.push_back(MakeRecord(list[i].first, list[i].second, a.train));
    // The progress bar goes to stderr (only on a terminal).
    Progress("import: target", int(i + 1), int(list.size()));
  }
  store.AddAll(records);  // all or none
  std::printf("imported %zu targets into %s in %.1f s (%zu targets now)\n", records.size(), a.db.c_str(),
              t.ElapsedMs() / 1000, store.Count());
  return 0;
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
  std::printf("%s: %zu targets (schema %d)\n", a.db.c_str(), list.size(), store.schema_version());
  for (const auto& i : list)
    std::printf("  %-24s %5dx%-5d %s%s%s\n", i.id.c_str(), i.width, i.height, i.title.c_str(),
                i.artist.empty() ? "" : " - ", i.artist.c_str());
  return 0;
}

int RunRemove(DbArgs& a) {
  TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
  Require(store.Remove(a.id), ErrorCode::kInvalidArgument, a.db + ": no target '" + a.id + "'");
  std::printf("removed '%s' from %s (%zu targets left)\n", a.id.c_str(), a.db.c_str(), store.Count());
  return 0;
}

int RunExport(DbArgs& a) {
  const TargetStore store = TargetStore::Open(a.db);
  nlohmann::json j = {{"database", a.db}, {"schema", store.schema_version()}, {"targets", nlohmann::json::array()}};
  for (const auto& i : store.List()) j["targets"].push_back(InfoJson(i));
  if (a.output.empty()) {
    std::cout << j.dump(1) << std::endl;
  } else {
    std::ofstream out(a.output);
    out << j.dump(1) << "\n";
    Require(bool(out), ErrorCode::kIo, a.output + ": cannot write");
    std::printf("exported %zu targets to %s\n", j["targets"].size(), a.output.c_str());
  }
  return 0;
}

}  // namespace

void RegisterDb(CLI::App& app, int* code) {
  auto* db = app.add_subcommand("db", "Target database: create, add, import, list, remove, export");
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
  AddTrainOptions(add, &a->train);
  add->callback([a, code] { *code = RunAdd(*a); });

  auto* imp = db->add_subcommand("import", "Train and add every target of a CSV or JSON list (all or none)");
  imp->add_option("DB", a->db, "database file")->required();
  imp->add_option("LIST", a->list, "LIST.csv (id,image,title,artist,year,url,meta) or LIST.json")->required();
  AddTrainOptions(imp, &a->train);
  imp->callback([a, code] { *code = RunImport(*a); });

  auto* list = db->add_subcommand("list", "List the targets");
  list->add_option("DB", a->db, "database file")->required();
  list->add_flag("--json", a->json, "a JSON array");
  list->callback([a, code] { *code = RunList(*a); });

  auto* rm = db->add_subcommand("remove", "Remove a target (one transaction)");
  rm->add_option("DB", a->db, "database file")->required();
  rm->add_option("ID", a->id, "target id")->required();
  rm->callback([a, code] { *code = RunRemove(*a); });

  auto* ex = db->add_subcommand("export", "Print (or write) every target's metadata as JSON");
  ex->add_option("DB", a->db, "database file")->required();
  ex->add_option("-o,--output", a->output, "write here instead of stdout");
  ex->callback([a, code] { *code = RunExport(*a); });
}

}  // namespace mvkp::cli
