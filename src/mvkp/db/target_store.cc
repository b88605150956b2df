// Target database on SQLite (see target_store.h).
//
// Design notes:
// - WAL journaling: readers (other connections, other processes) never block
//   the writer and never see a half-committed transaction; a crash at any
//   point leaves the last committed state (WAL recovery on the next open).
// - synchronous=FULL: the WAL is fsync'ed at every commit, so an add that
//   returned survives a power loss too, not only a process crash. Adds are
//   rare and follow seconds of training, so one fsync per commit costs nothing
//   that matters (NORMAL would only risk losing the last commits on power
//   loss, never corrupt the file).
// - busy timeout 5 s: a second writer (or a reader that has to run WAL
//   recovery) waits for the lock instead of failing with SQLITE_BUSY. Every
//   write transaction starts with BEGIN IMMEDIATE, so two writers can never
//   deadlock on a read->write lock upgrade (which no busy handler can resolve).
// - The file is recognised by PRAGMA application_id = kApplicationId and its
//   schema version is PRAGMA user_version. kMigrations[v] upgrades version v to
//   v + 1; Create runs them all from version 0 (empty file), Open runs the
//   missing ones in one BEGIN IMMEDIATE transaction.
// - Column order puts the big blobs last (model before image): SQLite stores a
//   row's columns in order, and reading a column after a blob walks the blob's
//   overflow pages, so List() never touches the blobs and LoadAll() never
//   touches the images.
// - Thread safety: one TargetStore (one connection, opened NOMUTEX) is for one
//   thread at a time; separate TargetStore objects, in threads or processes,
//   may read concurrently while at most one of them writes.
#include "mvkp/db/target_store.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <cctype>
#include <iterator>
#include <nlohmann/json.hpp>
#include <utility>

#include "mvkp/core/error.h"
#include "mvkp/db/json_limits.h"

namespace mvkp {
namespace {

constexpr int kApplicationId = 0x4d564b50;  // "MVKP"
constexpr int kBusyTimeoutMs = 5000;
constexpr std::size_t kMaxIdBytes = 256;

// kMigrations[v] upgrades schema version v to v + 1; version 0 is an empty
// database (only the application_id set). Append, never edit, when the schema
// changes, and bump kTargetStoreSchemaVersion.
constexpr const char* kMigrations[] = {
    // 0 -> 1: the targets table.
    "CREATE TABLE targets("
    " id TEXT PRIMARY KEY NOT NULL,"
    " title TEXT NOT NULL DEFAULT '',"
    " artist TEXT NOT NULL DEFAULT '',"
    " year TEXT NOT NULL DEFAULT '',"
    " url TEXT NOT NULL DEFAULT '',"
    " meta TEXT NOT NULL DEFAULT '{}',"
    " width INTEGER NOT NULL DEFAULT 0,"
    " height INTEGER NOT NULL DEFAULT 0,"
    " added_at TEXT NOT NULL DEFAULT '',"
    " model BLOB NOT NULL,"
    " image BLOB NOT NULL DEFAULT x'');",
    // 1 -> 2: derived forms of a target's model, by kind (e.g. "words": the
    // word search's compact encoding), so a recogniser need not decode every
    // model. Optional: a target without one is encoded from its model.
    "CREATE TABLE encodings("
    " id TEXT NOT NULL,"
    " kind TEXT NOT NULL,"
    " data BLOB NOT NULL,"
    " PRIMARY KEY (id, kind));",
};
static_assert(std::size(kMigrations) == kTargetStoreSchemaVersion,
              "one migration per schema version");

// Columns the current schema must have (checked on open).
constexpr const char* kColumns[] = {"id",    "title",  "artist",   "year",  "url",  "meta",
                                    "width", "height", "added_at", "model", "image"};

constexpr const char* kInfoColumns = "id, title, artist, year, url, meta, width, height, added_at";

bool ValidUtf8(const std::string& s) {
  std::size_t i = 0;
  const auto* p = reinterpret_cast<const unsigned char*>(s.data());
  while (i < s.size()) {
    const unsigned c = p[i];
    int n;
    std::uint32_t cp;
    if (c < 0x80) { ++i; continue; }
    if ((c & 0xE0) == 0xC0) { n = 1; cp = c & 0x1F; }
    else if ((c & 0xF0) == 0xE0) { n = 2; cp = c & 0x0F; }
    else if ((c & 0xF8) == 0xF0) { n = 3; cp = c & 0x07; }
    else return false;
    if (i + n >= s.size()) return false;  // truncated sequence
    for (int k = 1; k <= n; ++k) {
      if ((p[i + k] & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (p[i + k] & 0x3F);
    }
    static constexpr std::uint32_t kMin[] = {0, 0x80, 0x800, 0x10000};
    if (cp < kMin[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    i += n + 1;
  }
  return true;
}

// One connection and what we know about its file.
struct Conn {
  sqlite3* db = nullptr;
  std::string path;
  bool read_only = true;
  int version = 0;

  Conn() = default;
  Conn(const Conn&) = delete;
  Conn& operator=(const Conn&) = delete;
  ~Conn() { sqlite3_close_v2(db); }

  // Error(kIo, "<path>: DB: <sqlite message>"); corrupt / not-a-database
  // files are kBadModel, as for the other file formats.
  [[noreturn]] void Fail(int rc) const {
    const int primary = rc & 0xff;
    const char* msg = db && sqlite3_extended_errcode(db) == rc ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
    const ErrorCode code =
        primary == SQLITE_NOTADB || primary == SQLITE_CORRUPT ? ErrorCode::kBadModel : ErrorCode::kIo;
    throw Error(code, path + ": DB: " + msg);
  }
  void Check(int rc) const {
    if (rc != SQLITE_OK) Fail(rc);
  }
  void Exec(const char* sql) const { Check(sqlite3_exec(db, sql, nullptr, nullptr, nullptr)); }
  void RequireWritable() const {
    Require(!read_only, ErrorCode::kInvalidArgument, path + ": DB: opened read-only");
  }
  [[noreturn]] void NotOurs() const {
    throw Error(ErrorCode::kBadModel, path + ": DB: not an mvkp target database");
  }

  int PragmaInt(const char* sql) const;
  void Migrate();  // inside a write transaction
  void CheckSchema() const;
  void Insert(const TargetRecord& r, const std::string& added_at);
  void Connect(const std::string& file, bool ro);
};

// A prepared statement; values are always bound, never spliced into SQL.
struct Stmt {
  const Conn& s;
  sqlite3_stmt* st = nullptr;

  Stmt(const Conn& store, const char* sql) : s(store) {
    s.Check(sqlite3_prepare_v2(s.db, sql, -1, &st, nullptr));
  }
  ~Stmt() { sqlite3_finalize(st); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  // The bound buffers must outlive the Step() calls (SQLITE_STATIC, no copy of
  // a 20 MB model).
  Stmt& Text(int i, const std::string& v) {
    s.Check(sqlite3_bind_text64(st, i, v.data(), v.size(), SQLITE_STATIC, SQLITE_UTF8));
    return *this;
  }
  Stmt& Blob(int i, const std::vector<std::uint8_t>& v) {
    // A null pointer would bind NULL, not an empty blob.
    s.Check(v.empty() ? sqlite3_bind_zeroblob(st, i, 0)
                      : sqlite3_bind_blob64(st, i, v.data(), v.size(), SQLITE_STATIC));
    return *this;
  }
  Stmt& Int(int i, int v) {
    s.Check(sqlite3_bind_int(st, i, v));
    return *this;
  }
  int StepRc() { return sqlite3_step(st); }
  // True for a row, false when done; throws on an error.
  bool Step() {
    const int rc = StepRc();
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    s.Fail(rc);
  }
  std::string ColText(int i) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(st, i));
    return p ? std::string(p, std::size_t(sqlite3_column_bytes(st, i))) : std::string();
  }
  std::vector<std::uint8_t> ColBlob(int i) const {
    const auto* p = static_cast<const std::uint8_t*>(sqlite3_column_blob(st, i));
    const int n = sqlite3_column_bytes(st, i);
    return p && n > 0 ? std::vector<std::uint8_t>(p, p + n) : std::vector<std::uint8_t>();
  }
  int ColInt(int i) const { return sqlite3_column_int(st, i); }
  TargetInfo ColInfo() const {  // kInfoColumns at 0..8
    TargetInfo info;
    info.id = ColText(0);
    info.title = ColText(1);
    info.artist = ColText(2);
    info.year = ColText(3);
    info.url = ColText(4);
    info.meta = ColText(5);
    info.width = ColInt(6);
    info.height = ColInt(7);
    info.added_at = ColText(8);
    return info;
  }
};

// BEGIN IMMEDIATE ... COMMIT; rolls back unless Commit() succeeded.
class WriteTxn {
 public:
  explicit WriteTxn(const Conn& s) : s_(s) { s_.Exec("BEGIN IMMEDIATE"); }
  ~WriteTxn() {
    if (!sqlite3_get_autocommit(s_.db)) sqlite3_exec(s_.db, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  WriteTxn(const WriteTxn&) = delete;
  WriteTxn& operator=(const WriteTxn&) = delete;
  void Commit() { s_.Exec("COMMIT"); }

 private:
  const Conn& s_;
};

void ValidateInfo(const std::string& path, const TargetInfo& info, bool new_id) {
  const std::string bad = path + ": invalid target id";
  Require(!info.id.empty(), ErrorCode::kInvalidArgument, bad + ": empty");
  Require(info.id.size() <= kMaxIdBytes, ErrorCode::kInvalidArgument,
          bad + ": " + std::to_string(info.id.size()) + " bytes, at most " + std::to_string(kMaxIdBytes));
  for (std::size_t i = 0; i < info.id.size(); ++i) {
    const auto c = static_cast<unsigned char>(info.id[i]);
    Require(c >= 0x20 && c != 0x7f, ErrorCode::kInvalidArgument,
            bad + ": control character at byte " + std::to_string(i));
  }
  Require(ValidUtf8(info.id), ErrorCode::kInvalidArgument, bad + ": not valid UTF-8");
  if (new_id) {
    auto alnum = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'); };
    Require(alnum(info.id[0]), ErrorCode::kInvalidArgument,
            bad + " '" + info.id + "': must start with a letter or digit");
    for (char c : info.id)
      Require(alnum(c) || c == '.' || c == '_' || c == '-', ErrorCode::kInvalidArgument,
              bad + " '" + info.id + "': only ASCII letters, digits, '.', '_' and '-' are allowed");
  }
  const std::string who = path + ": target '" + info.id + "': ";
  auto text = [&](const char* field, const std::string& v, std::size_t max) {
    Require(v.size() <= max, ErrorCode::kInvalidArgument,
            who + field + " is " + std::to_string(v.size()) + " bytes, at most " + std::to_string(max));
    Require(ValidUtf8(v), ErrorCode::kInvalidArgument, who + field + " is not valid UTF-8");
    for (unsigned char c : v)
      Require(c >= 0x20 && c != 0x7f, ErrorCode::kInvalidArgument, who + field + " contains a control character");
  };
  text("title", info.title, 1000);
  text("artist", info.artist, 1000);
  text("year", info.year, 100);
  text("url", info.url, 2000);
  if (!info.url.empty()) {
    std::string lower = info.url.substr(0, 8);
    for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
    const std::size_t rest = lower.rfind("https://", 0) == 0 ? 8 : lower.rfind("http://", 0) == 0 ? 7 : 0;
    Require(rest > 0 && info.url.size() > rest, ErrorCode::kInvalidArgument,
            who + "url must be an absolute http:// or https:// URL");
    Require(info.url.find_first_of(" \"<>`") == std::string::npos, ErrorCode::kInvalidArgument,
            who + "url must not contain spaces, quotes or angle brackets");
  }
  Require(info.width >= 0 && info.height >= 0, ErrorCode::kInvalidArgument, who + "negative image size");
  const nlohmann::json meta = ParseJsonLimited(info.meta, MetaJsonLimits(), who + "meta");
  Require(meta.is_object(), ErrorCode::kInvalidArgument, who + "meta must be a JSON object");
}

void ValidateRecord(const std::string& path, const TargetRecord& r) {
  ValidateInfo(path, r.info, /*new_id=*/true);
  Require(!r.model.empty(), ErrorCode::kInvalidArgument, path + ": target '" + r.info.id + "': empty model");
}

}  // namespace

std::string NowUtcIso8601() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

void ValidateTargetInfo(const TargetInfo& info, bool new_id, const std::string& where) {
  ValidateInfo(where, info, new_id);
}

struct TargetStore::Impl : Conn {};

int Conn::PragmaInt(const char* sql) const {
  Stmt st(*this, sql);
  return st.Step() ? st.ColInt(0) : 0;
}

void Conn::Migrate() {
  const int from = PragmaInt("PRAGMA user_version");  // re-read under the write lock
  if (from > kTargetStoreSchemaVersion) {
    throw Error(ErrorCode::kBadModel, path + ": DB: schema version " + std::to_string(from) +
                                          " is newer than this build's " +
                                          std::to_string(kTargetStoreSchemaVersion));
  }
  for (int v = from; v < kTargetStoreSchemaVersion; ++v) Exec(kMigrations[v]);
  // PRAGMA takes no bound parameters; the value is our own constant.
  Exec(("PRAGMA user_version = " + std::to_string(kTargetStoreSchemaVersion)).c_str());
  version = kTargetStoreSchemaVersion;
}

void Conn::CheckSchema() const {
  Stmt st(*this, "SELECT name FROM pragma_table_info('targets')");
  std::vector<std::string> have;
  while (st.Step()) have.push_back(st.ColText(0));
  for (const char* c : kColumns) {
    if (std::find(have.begin(), have.end(), c) == have.end()) NotOurs();
  }
}

void Conn::Insert(const TargetRecord& r, const std::string& added_at) {
  Stmt st(*this,
          "INSERT INTO targets(id, title, artist, year, url, meta, width, height, added_at, model, image)"
          " VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)");
  st.Text(1, r.info.id)
      .Text(2, r.info.title)
      .Text(3, r.info.artist)
      .Text(4, r.info.year)
      .Text(5, r.info.url)
      .Text(6, r.info.meta)
      .Int(7, r.info.width)
      .Int(8, r.info.height)
      .Text(9, added_at)
      .Blob(10, r.model)
      .Blob(11, r.image);
  const int rc = st.StepRc();
  if (rc == SQLITE_CONSTRAINT_PRIMARYKEY) {
    throw Error(ErrorCode::kInvalidArgument, path + ": target '" + r.info.id + "' already exists");
  }
  if (rc != SQLITE_DONE) Fail(rc);
  for (const auto& [kind, data] : r.encodings) {
    Stmt e(*this, "INSERT INTO encodings(id, kind, data) VALUES (?1, ?2, ?3)");
    e.Text(1, r.info.id).Text(2, kind).Blob(3, data);
    e.Step();
  }
}

void Conn::Connect(const std::string& file, bool ro) {
  path = file;
  read_only = ro;
  // NOMUTEX: one connection per thread (see the notes at the top).
  const int flags = (ro ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE) | SQLITE_OPEN_NOMUTEX;
  const int rc = sqlite3_open_v2(path.c_str(), &db, flags, nullptr);
  if (rc != SQLITE_OK) {
    if (!db) throw Error(ErrorCode::kIo, path + ": DB: " + sqlite3_errstr(rc));
    Fail(rc);
  }
  sqlite3_extended_result_codes(db, 1);
  Check(sqlite3_busy_timeout(db, kBusyTimeoutMs));
  // The file may come from anywhere: no writable_schema tricks, no
  // functions with side effects called from its schema.
  sqlite3_db_config(db, SQLITE_DBCONFIG_DEFENSIVE, 1, nullptr);
#ifdef SQLITE_DBCONFIG_TRUSTED_SCHEMA
  sqlite3_db_config(db, SQLITE_DBCONFIG_TRUSTED_SCHEMA, 0, nullptr);
#endif
}

TargetStore::TargetStore(Impl* impl) : impl_(impl) {}
TargetStore::TargetStore(TargetStore&& o) noexcept : impl_(std::exchange(o.impl_, nullptr)) {}
TargetStore& TargetStore::operator=(TargetStore&& o) noexcept {
  if (this != &o) {
    delete impl_;
    impl_ = std::exchange(o.impl_, nullptr);
  }
  return *this;
}
TargetStore::~TargetStore() { delete impl_; }

const std::string& TargetStore::path() const { return impl_->path; }
int TargetStore::schema_version() const { return impl_->version; }

TargetStore TargetStore::Create(const std::string& path) {
  Require(!path.empty(), ErrorCode::kInvalidArgument, "DB: empty database path");
  // A leftover journal of an earlier file with this name would be replayed
  // into the new one.
  for (const char* suffix : {"-wal", "-journal"}) {
    struct stat st {};
    Require(::lstat((path + suffix).c_str(), &st) != 0, ErrorCode::kIo,
            path + ": DB: a stale " + path + suffix + " exists; remove it first");
  }
  // O_EXCL: atomically refuse an existing path (no check-then-create race).
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    throw Error(ErrorCode::kIo, path + (err == EEXIST ? ": DB: already exists"
                                                      : ": DB: cannot create: " + std::string(std::strerror(err))));
  }
  ::close(fd);
  try {
    auto* impl = new Impl;
    TargetStore store(impl);  // owns impl from here
    impl->Connect(path, /*ro=*/false);
    {
      Stmt wal(*impl, "PRAGMA journal_mode = WAL");
      Require(wal.Step() && wal.ColText(0) == "wal", ErrorCode::kIo,
              path + ": DB: cannot enable WAL journaling on this file system");
    }
    impl->Exec("PRAGMA synchronous = FULL");
    impl->Exec("PRAGMA journal_size_limit = 67108864");
    {
      WriteTxn txn(*impl);
      impl->Exec(("PRAGMA application_id = " + std::to_string(kApplicationId)).c_str());
      impl->Migrate();
      txn.Commit();
    }
    return store;
  } catch (...) {
    // store (if made) closed the connection; remove the half-made file.
    std::error_code ec;
    for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path + suffix, ec);
    throw;
  }
}

TargetStore TargetStore::Open(const std::string& path, Mode mode) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    throw Error(ErrorCode::kIo, path + (err == ENOENT ? ": DB: no such database"
                                                      : ": DB: " + std::string(std::strerror(err))));
  }
  Require(S_ISREG(st.st_mode), ErrorCode::kIo, path + ": DB: not a regular file");
  TargetStore store(new Impl);
  Impl& s = *store.impl_;
  s.Connect(path, mode == Mode::kReadOnly);

  int app_id = 0;
  try {
    app_id = s.PragmaInt("PRAGMA application_id");  // first read: SQLITE_NOTADB for a non-SQLite file
  } catch (const Error&) {
    if ((sqlite3_extended_errcode(s.db) & 0xff) == SQLITE_NOTADB) s.NotOurs();
    throw;
  }
  if (app_id != kApplicationId) s.NotOurs();
  s.version = s.PragmaInt("PRAGMA user_version");
  if (s.version > kTargetStoreSchemaVersion) {
    throw Error(ErrorCode::kBadModel, path + ": DB: schema version " + std::to_string(s.version) +
                                          " is newer than this build's " +
                                          std::to_string(kTargetStoreSchemaVersion));
  }
  if (!s.read_only) {
    // Only now that the file is known to be ours do we change anything.
    {
      Stmt wal(s, "PRAGMA journal_mode = WAL");
      Require(wal.Step() && wal.ColText(0) == "wal", ErrorCode::kIo,
              path + ": DB: cannot enable WAL journaling on this file system");
    }
    s.Exec("PRAGMA synchronous = FULL");
    s.Exec("PRAGMA journal_size_limit = 67108864");
    if (s.version < kTargetStoreSchemaVersion) {
      WriteTxn txn(s);
      s.Migrate();
      txn.Commit();
    }
  } else if (s.version < 1) {
    // Version 1 is readable as it is (later versions only add optional
    // tables); an empty version-0 file is not a database yet.
    throw Error(ErrorCode::kBadModel, path + ": DB: schema version " + std::to_string(s.version) +
                                          " is older than this build's " +
                                          std::to_string(kTargetStoreSchemaVersion) +
                                          "; open it read-write once to migrate it");
  }
  s.CheckSchema();
  return store;
}

void TargetStore::Add(const TargetRecord& record) {
  impl_->RequireWritable();
  ValidateRecord(impl_->path, record);
  WriteTxn txn(*impl_);
  impl_->Insert(record, NowUtcIso8601());
  txn.Commit();
}

void TargetStore::AddAll(const std::vector<TargetRecord>& records) {
  impl_->RequireWritable();
  for (const auto& r : records) ValidateRecord(impl_->path, r);  // before taking the lock
  const std::string now = NowUtcIso8601();
  WriteTxn txn(*impl_);
  for (const auto& r : records) impl_->Insert(r, now);  // a duplicate rolls everything back
  txn.Commit();
}

void TargetStore::Restore(const std::vector<TargetRecord>& records) {
  impl_->RequireWritable();
  for (const auto& r : records) {
    ValidateRecord(impl_->path, r);
    Require(!r.info.added_at.empty(), ErrorCode::kInvalidArgument,
            impl_->path + ": target '" + r.info.id + "': restore needs added_at");
  }
  WriteTxn txn(*impl_);
  for (const auto& r : records) impl_->Insert(r, r.info.added_at);
  txn.Commit();
}

bool TargetStore::ReplaceImage(const TargetRecord& r) {
  impl_->RequireWritable();
  Require(!r.model.empty(), ErrorCode::kInvalidArgument, impl_->path + ": target '" + r.info.id + "': empty model");
  Require(r.info.width >= 0 && r.info.height >= 0, ErrorCode::kInvalidArgument,
          impl_->path + ": target '" + r.info.id + "': negative image size");
  const std::string now = NowUtcIso8601();
  WriteTxn txn(*impl_);
  Stmt st(*impl_, "UPDATE targets SET width = ?2, height = ?3, model = ?4, image = ?5, added_at = ?6 WHERE id = ?1");
  st.Text(1, r.info.id).Int(2, r.info.width).Int(3, r.info.height).Blob(4, r.model).Blob(5, r.image).Text(6, now);
  st.Step();
  if (sqlite3_changes(impl_->db) == 0) return false;  // rolled back (nothing written)
  Stmt del(*impl_, "DELETE FROM encodings WHERE id = ?1");
  del.Text(1, r.info.id);
  del.Step();
  for (const auto& [kind, data] : r.encodings) {
    Stmt e(*impl_, "INSERT INTO encodings(id, kind, data) VALUES (?1, ?2, ?3)");
    e.Text(1, r.info.id).Text(2, kind).Blob(3, data);
    e.Step();
  }
  txn.Commit();
  return true;
}

bool TargetStore::Remove(const std::string& id) {
  impl_->RequireWritable();
  WriteTxn txn(*impl_);
  Stmt st(*impl_, "DELETE FROM targets WHERE id = ?1");
  st.Text(1, id);
  st.Step();
  const bool removed = sqlite3_changes(impl_->db) > 0;
  Stmt enc(*impl_, "DELETE FROM encodings WHERE id = ?1");
  enc.Text(1, id);
  enc.Step();
  txn.Commit();
  return removed;
}

bool TargetStore::UpdateInfo(const TargetInfo& info) {
  impl_->RequireWritable();
  ValidateInfo(impl_->path, info, /*new_id=*/false);
  WriteTxn txn(*impl_);
  // The image, its size, the model and added_at stay as they are.
  Stmt st(*impl_, "UPDATE targets SET title = ?2, artist = ?3, year = ?4, url = ?5, meta = ?6 WHERE id = ?1");
  st.Text(1, info.id).Text(2, info.title).Text(3, info.artist).Text(4, info.year).Text(5, info.url).Text(6, info.meta);
  st.Step();
  const bool updated = sqlite3_changes(impl_->db) > 0;
  txn.Commit();
  return updated;
}

bool TargetStore::Contains(const std::string& id) const {
  Stmt st(*impl_, "SELECT 1 FROM targets WHERE id = ?1");
  st.Text(1, id);
  return st.Step();
}

std::uint64_t TargetStore::DataVersion() const {
  Stmt st(*impl_, "PRAGMA data_version");
  st.Step();
  return std::uint64_t(sqlite3_column_int64(st.st, 0));
}

std::size_t TargetStore::Count() const {
  Stmt st(*impl_, "SELECT count(*) FROM targets");
  st.Step();
  return std::size_t(sqlite3_column_int64(st.st, 0));
}

std::vector<TargetInfo> TargetStore::List() const {
  Stmt st(*impl_, (std::string("SELECT ") + kInfoColumns + " FROM targets ORDER BY id").c_str());
  std::vector<TargetInfo> out;
  while (st.Step()) out.push_back(st.ColInfo());
  return out;
}

TargetRecord TargetStore::Get(const std::string& id, bool with_image) const {
  const std::string sql = std::string("SELECT ") + kInfoColumns + ", model" + (with_image ? ", image" : "") +
                          " FROM targets WHERE id = ?1";
  Stmt st(*impl_, sql.c_str());
  st.Text(1, id);
  Require(st.Step(), ErrorCode::kInvalidArgument, impl_->path + ": no target '" + id + "'");
  TargetRecord r;
  r.info = st.ColInfo();
  r.model = st.ColBlob(9);
  if (with_image) r.image = st.ColBlob(10);
  return r;
}

std::vector<std::pair<TargetInfo, std::vector<std::uint8_t>>> TargetStore::LoadEncodings(const std::string& kind) const {
  std::vector<std::pair<TargetInfo, std::vector<std::uint8_t>>> out;
  if (impl_->version < 2) return out;  // a version-1 file opened read-only has none
  Stmt st(*impl_, "SELECT t.id, t.title, t.artist, t.year, t.url, t.meta, t.width, t.height, t.added_at, e.data"
                  " FROM targets t JOIN encodings e ON e.id = t.id AND e.kind = ?1 ORDER BY t.id");
  st.Text(1, kind);
  while (st.Step()) out.emplace_back(st.ColInfo(), st.ColBlob(9));
  return out;
}

std::vector<std::pair<std::string, std::vector<std::uint8_t>>> TargetStore::Encodings(const std::string& id) const {
  std::vector<std::pair<std::string, std::vector<std::uint8_t>>> out;
  if (impl_->version < 2) return out;
  Stmt st(*impl_, "SELECT kind, data FROM encodings WHERE id = ?1 ORDER BY kind");
  st.Text(1, id);
  while (st.Step()) out.emplace_back(st.ColText(0), st.ColBlob(1));
  return out;
}

std::vector<TargetRecord> TargetStore::LoadAll() const {
  Stmt st(*impl_, (std::string("SELECT ") + kInfoColumns + ", model FROM targets ORDER BY id").c_str());
  std::vector<TargetRecord> out;
  while (st.Step()) {
    TargetRecord r;
    r.info = st.ColInfo();
    r.model = st.ColBlob(9);
    out.push_back(std::move(r));
  }
  return out;
}

// --- online backup ---------------------------------------------------------

void BackupOptions::Check() const {
  Require(pages_per_step > 0, ErrorCode::kInvalidArgument, "backup: pages_per_step must be positive");
  Require(busy_sleep_ms >= 0, ErrorCode::kInvalidArgument, "backup: busy_sleep_ms must not be negative");
  Require(timeout_s > 0, ErrorCode::kInvalidArgument, "backup: timeout_s must be positive");
  Require(restarts_before_one_step >= 0, ErrorCode::kInvalidArgument,
          "backup: restarts_before_one_step must not be negative");
}

namespace {

// The temporary copy beside `out`: removed (with its journals) unless kept.
struct TempCopy {
  std::string path;
  bool keep = false;
  ~TempCopy() {
    if (keep || path.empty()) return;
    std::error_code ec;
    for (const char* suffix : {"", "-wal", "-shm", "-journal"}) std::filesystem::remove(path + suffix, ec);
  }
};

void SyncPath(const std::string& path, bool directory, const std::string& what) {
  const int fd = ::open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDWR) | O_CLOEXEC);
  Require(fd >= 0, ErrorCode::kIo, what + ": cannot open " + path + " to sync: " + std::strerror(errno));
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  Require(rc == 0, ErrorCode::kIo, what + ": cannot sync " + path + ": " + std::strerror(err));
}

}  // namespace

BackupReport BackupTargetStore(const std::string& db, const std::string& out, const BackupOptions& options) {
  namespace fs = std::filesystem;
  options.Check();
  const std::string what = out + ": backup";
  Require(!out.empty(), ErrorCode::kInvalidArgument, "backup: empty output path");
  // Ours and readable (throws as Open does), then a connection of our own to
  // copy from (a write through any other connection restarts the copy).
  TargetStore::Open(db, TargetStore::Mode::kReadOnly);
  Conn source;
  source.Connect(db, /*ro=*/true);
  // SQLITE_BUSY comes back to the loop below at once, which sleeps and
  // retries until options.timeout_s (not SQLite's 5 s per step).
  source.Check(sqlite3_busy_timeout(source.db, 0));
  std::error_code ec;
  if (fs::exists(out, ec)) {
    Require(!fs::equivalent(db, out, ec), ErrorCode::kIo, what + ": the output is the database itself");
    Require(options.overwrite, ErrorCode::kIo, what + ": already exists (give --force to replace it)");
    Require(fs::is_regular_file(out, ec), ErrorCode::kIo, what + ": exists and is not a regular file");
  }
  // A stale journal of an earlier file named `out` would be replayed into the
  // copy (an empty one, as a read-only reader of a copy leaves, is harmless).
  for (const char* suffix : {"-wal", "-journal"}) {
    struct stat st {};
    Require(::lstat((out + suffix).c_str(), &st) != 0 || (S_ISREG(st.st_mode) && st.st_size == 0), ErrorCode::kIo,
            what + ": a stale " + out + suffix + " exists; remove it first");
  }

  TempCopy tmp;
  {
    const fs::path dir = fs::path(out).parent_path();
    std::string name = ".";
    name += fs::path(out).filename().string();
    name += ".tmp-XXXXXX";
    std::string templ = ((dir.empty() ? fs::path(".") : dir) / name).string();
    const int fd = ::mkstemp(templ.data());
    Require(fd >= 0, ErrorCode::kIo, what + ": cannot create a temporary file beside it: " + std::strerror(errno));
    ::close(fd);
    ::chmod(templ.c_str(), 0644);
    tmp.path = templ;
  }

  BackupReport report;
  {
    Conn dest;
    dest.Connect(tmp.path, /*ro=*/false);
    sqlite3_backup* b = sqlite3_backup_init(dest.db, "main", source.db, "main");
    if (!b) dest.Fail(sqlite3_extended_errcode(dest.db));
    const auto start = std::chrono::steady_clock::now();
    int last_remaining = -1;
    int rc = SQLITE_OK;
    for (;;) {
      const bool one_step = report.restarts >= options.restarts_before_one_step;
      rc = sqlite3_backup_step(b, one_step ? -1 : options.pages_per_step);
      if (rc == SQLITE_DONE) break;
      const int primary = rc & 0xff;
      if (rc == SQLITE_OK || primary == SQLITE_BUSY || primary == SQLITE_LOCKED) {
        if (rc == SQLITE_OK) {
          ++report.steps;
          const int remaining = sqlite3_backup_remaining(b);
          if (last_remaining >= 0 && remaining > last_remaining) ++report.restarts;  // the source changed
          last_remaining = remaining;
        } else {
          ++report.busy_retries;
        }
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (s > options.timeout_s) {
          sqlite3_backup_finish(b);
          throw Error(ErrorCode::kIo, what + ": timed out after " + std::to_string(int(options.timeout_s)) +
                                          " s (the database stayed busy: " + sqlite3_errstr(rc) + ")");
        }
        if (rc != SQLITE_OK) ::usleep(useconds_t(options.busy_sleep_ms) * 1000);
        continue;
      }
      break;  // an error
    }
    report.pages = std::size_t(sqlite3_backup_pagecount(b));
    const int fin = sqlite3_backup_finish(b);
    if (rc != SQLITE_DONE) throw Error(ErrorCode::kIo, what + ": " + sqlite3_errstr(rc) + " while copying " + db);
    if (fin != SQLITE_OK) dest.Fail(fin);
    // The copy must be whole and ours before it takes the name.
    {
      Stmt check(dest, "PRAGMA integrity_check");
      std::string problems;
      while (check.Step()) {
        const std::string row = check.ColText(0);
        if (row != "ok") problems += (problems.empty() ? "" : "; ") + row;
      }
      Require(problems.empty(), ErrorCode::kIo, what + ": the copy fails PRAGMA integrity_check: " + problems.substr(0, 500));
    }
    Require(dest.PragmaInt("PRAGMA application_id") == kApplicationId, ErrorCode::kIo,
            what + ": the copy is not an mvkp target database");
    {
      Stmt n(dest, "SELECT count(*) FROM targets");
      n.Step();
      report.targets = std::size_t(sqlite3_column_int64(n.st, 0));
    }
    // Fold a WAL the checks may have opened back into the file.
    sqlite3_exec(dest.db, "PRAGMA wal_checkpoint(TRUNCATE)", nullptr, nullptr, nullptr);
  }  // closed: the copy is one file now
  for (const char* suffix : {"-wal", "-shm"}) fs::remove(tmp.path + suffix, ec);
  SyncPath(tmp.path, false, what);
  if (options.overwrite) {
    Require(::rename(tmp.path.c_str(), out.c_str()) == 0, ErrorCode::kIo,
            what + ": cannot rename the copy into place: " + std::strerror(errno));
  } else {
    // link() refuses an existing name atomically (no check-then-rename race).
    if (::link(tmp.path.c_str(), out.c_str()) != 0) {
      const int err = errno;
      throw Error(ErrorCode::kIo, what + (err == EEXIST ? ": already exists (give --force to replace it)"
                                                        : ": cannot move the copy into place: " + std::string(std::strerror(err))));
    }
    ::unlink(tmp.path.c_str());
  }
  tmp.keep = true;
  const fs::path dir = fs::path(out).parent_path();
  SyncPath(dir.empty() ? "." : dir.string(), true, what);
  return report;
}

}  // namespace mvkp
