// Target database storage (issue 6, thesis §6.3.2): one SQLite file holds the
// targets, their metadata and their trained models.
//
// Schema (version kTargetStoreSchemaVersion, in PRAGMA user_version):
//   targets(id TEXT PRIMARY KEY, title TEXT, artist TEXT, year TEXT, url TEXT,
//           meta TEXT (free-form JSON, '{}' by default), width INTEGER,
//           height INTEGER, image BLOB (the encoded target image, may be
//           empty), model BLOB (SerializeModel bytes), added_at TEXT (UTC ISO 8601))
//   encodings(id TEXT, kind TEXT, data BLOB; primary key (id, kind)): derived
//           forms of a target's model (schema 2), e.g. the word search's.
// Opening an older schema read-write migrates it in one transaction (read-only,
// a version-1 file is read as it is, without encodings); a newer one is
// refused. The file uses WAL journaling, so many readers (other processes
// included) can read while one writer adds or removes targets; every add or
// remove is one transaction, so a crash leaves either the old or the new
// state, never a half-written target.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace mvkp {

constexpr int kTargetStoreSchemaVersion = 2;

struct TargetInfo {
  // A new id: 1-256 bytes of ASCII letters, digits, '.', '_' and '-', starting
  // with a letter or digit (so no "." or ".."; ids are URL path segments).
  // Targets stored before that rule keep their ids (no control characters).
  std::string id;
  // UTF-8 without control characters; title and artist at most 1000 bytes,
  // year 100. url: empty or an absolute http:// or https:// URL of at most
  // 2000 bytes without spaces (it becomes a link on visitors' phones).
  std::string title, artist, year, url;
  std::string meta = "{}";  // a JSON object, at most 64 KiB and 16 levels deep
  int width = 0, height = 0;  // of the target image
  std::string added_at;       // set by the store
};

struct TargetRecord {
  TargetInfo info;
  std::vector<std::uint8_t> image;  // encoded image bytes (JPEG/PNG), may be empty
  std::vector<std::uint8_t> model;  // SerializeModel bytes
  // Derived forms stored with it (kind, bytes), e.g. {"words",
  // Recognizer::Encode(model)}; written by Add/AddAll, not read back by Get.
  std::vector<std::pair<std::string, std::vector<std::uint8_t>>> encodings;
};

// One TargetStore (one SQLite connection) is for one thread at a time;
// separate TargetStore objects, in threads or processes, may read
// concurrently while at most one writes (a second writer waits up to 5 s).
// Checks `info` as Add (`new_id`) or UpdateInfo would and throws
// Error(kInvalidArgument) naming `where`, the target and the field. It is
// cheap: callers that train before adding call it first.
void ValidateTargetInfo(const TargetInfo& info, bool new_id, const std::string& where = "target");

// The current time as the store writes it (added_at): UTC, ISO 8601 to the
// second, e.g. "2026-12-03T04:05:06Z".
std::string NowUtcIso8601();

// How BackupTargetStore copies a live database.
struct BackupOptions {
  int pages_per_step = 1024;  // pages per sqlite3_backup_step (4 MiB at 4 KiB pages)
  int busy_sleep_ms = 20;     // wait after SQLITE_BUSY / SQLITE_LOCKED, then retry
  double timeout_s = 60;      // give up with Error(kIo) after this long
  // A write by another connection between steps restarts the copy; after this
  // many restarts the rest is copied in one step (one WAL read snapshot, which
  // does not block writers), so a busy server cannot starve a backup.
  int restarts_before_one_step = 2;
  bool overwrite = false;  // replace an existing `out` (else Error(kIo))
  // Throws Error(kInvalidArgument) naming the field out of range.
  void Check() const;
};

struct BackupReport {
  std::size_t pages = 0;    // pages in the copy
  int steps = 0;            // sqlite3_backup_step calls that copied pages
  int busy_retries = 0;     // steps retried after SQLITE_BUSY / SQLITE_LOCKED
  int restarts = 0;         // copies restarted because the source changed
  std::size_t targets = 0;  // targets in the copy
};

// A consistent copy of the target database `db` at `out`, taken while other
// connections (a server, `mvkp db`) read and write it, with SQLite's online
// backup API: every transaction committed before the call is in the copy and
// every transaction is wholly in it or wholly not. The copy goes to a
// temporary file beside `out`, passes PRAGMA integrity_check, is synced and
// only then renamed to `out`, so `out` is either absent, the old file, or a
// whole checked copy. Throws Error(kIo) when `out` exists (unless
// options.overwrite) or is `db` itself, on a timeout or a write error, and as
// TargetStore::Open for a `db` that is not a target database.
BackupReport BackupTargetStore(const std::string& db, const std::string& out, const BackupOptions& options = {});

class TargetStore {
 public:
  enum class Mode { kReadOnly, kReadWrite };
  // Creates a new, empty database file. Throws Error(kIo) if the path exists
  // or cannot be created.
  static TargetStore Create(const std::string& path);
  // Opens an existing database. Throws Error(kIo) if missing/unreadable,
  // Error(kBadModel) ("not an mvkp target database", "schema version N is
  // newer than this build's M") if it is not one we can read.
  static TargetStore Open(const std::string& path, Mode mode = Mode::kReadOnly);

  TargetStore(TargetStore&&) noexcept;
  TargetStore& operator=(TargetStore&&) noexcept;
  TargetStore(const TargetStore&) = delete;
  TargetStore& operator=(const TargetStore&) = delete;
  ~TargetStore();

  const std::string& path() const;
  int schema_version() const;
  // SQLite's data_version of this store's connection: it changes whenever
  // another connection (this process or another) has committed a change
  // since the last call. A server polls it to pick up changes made by `mvkp
  // db` or by another replica's admin API.
  std::uint64_t DataVersion() const;

  // One transaction. Throws Error(kInvalidArgument) for a duplicate id
  // ("target 'X' already exists"), a bad id or invalid meta JSON; nothing is
  // written then.
  void Add(const TargetRecord& record);
  // Adds all or none (one transaction), e.g. for a bulk import.
  void AddAll(const std::vector<TargetRecord>& records);
  // As AddAll, but keeps each record's added_at (which must be set): a
  // restore from an archive (`mvkp db export`) gives the same rows.
  void Restore(const std::vector<TargetRecord>& records);
  // Replaces a target's image, size, model and encodings (`record.info.id`
  // names it; its other metadata stays) in one transaction and sets added_at
  // to now: it dates the image, and caches of thumbnails and quality reports
  // key on it. False if there is no such id.
  bool ReplaceImage(const TargetRecord& record);
  // One transaction. Returns false if there was no such id.
  bool Remove(const std::string& id);
  // Replaces the metadata (not the model); false if there is no such id.
  bool UpdateInfo(const TargetInfo& info);

  bool Contains(const std::string& id) const;
  std::size_t Count() const;
  // Metadata of every target, ordered by id.
  std::vector<TargetInfo> List() const;
  // Throws Error(kInvalidArgument) "no target 'X'" if absent.
  TargetRecord Get(const std::string& id, bool with_image = true) const;
  // Every target with its model (not the image), ordered by id: what a
  // recogniser loads.
  std::vector<TargetRecord> LoadAll() const;
  // The targets that have an encoding of `kind`, with it, ordered by id (none
  // from a version-1 file opened read-only).
  std::vector<std::pair<TargetInfo, std::vector<std::uint8_t>>> LoadEncodings(const std::string& kind) const;
  // Every encoding of one target (kind, bytes), ordered by kind.
  std::vector<std::pair<std::string, std::vector<std::uint8_t>>> Encodings(const std::string& id) const;

 private:
  struct Impl;
  explicit TargetStore(Impl* impl);
  Impl* impl_ = nullptr;
};

}  // namespace mvkp
