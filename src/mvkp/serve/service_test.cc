// The guide service against hostile and broken input (issue 19): each test
// reproduces one finding on a service running in this process on a free
// loopback port, and checks that it is refused cleanly while /healthz keeps
// answering.
#include "mvkp/serve/service.h"

#include <arpa/inet.h>
#include <httplib.h>
#include <netinet/in.h>
#include <sqlite3.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/db/target_store.h"
#include "mvkp/recognize/target_db.h"
#include "mvkp/serve/site.h"
#include "test_samples.h"

namespace mvkp::serve {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr const char* kToken = "0123456789abcdef-token";

std::vector<std::uint8_t> FileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::string SamplePath(const std::string& name) { return std::string(MVKP_SOURCE_DIR) + "/samples/" + name; }

void Sql(const std::string& db, const std::string& sql, const std::string& blob_or_text = "", bool blob = false) {
  sqlite3* h = nullptr;
  ASSERT_EQ(sqlite3_open(db.c_str(), &h), SQLITE_OK);
  sqlite3_busy_timeout(h, 5000);
  sqlite3_stmt* st = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(h, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(h);
  if (sql.find('?') != std::string::npos) {
    if (blob) sqlite3_bind_blob(st, 1, blob_or_text.data(), int(blob_or_text.size()), SQLITE_TRANSIENT);
    else sqlite3_bind_text(st, 1, blob_or_text.data(), int(blob_or_text.size()), SQLITE_TRANSIENT);
  }
  const int rc = sqlite3_step(st);
  EXPECT_TRUE(rc == SQLITE_DONE || rc == SQLITE_ROW) << sqlite3_errmsg(h);
  sqlite3_finalize(st);
  sqlite3_close(h);
}

// A service on a copy of the suite's database, stopped and joined at the end.
class Running {
 public:
  explicit Running(ServiceOptions o) : tls_(!o.cert.empty()) {
    o.port = 0;
    if (!o.log) o.log = [](const std::string&) {};
    service_ = std::make_unique<Service>(o);
    port_ = service_->Bind();
    thread_ = std::thread([this] { service_->Run(); });
    httplib::Client c = Client();
    for (int i = 0; i < 200; ++i) {
      if (auto r = c.Get("/healthz"); r && r->status == 200) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ADD_FAILURE() << "service did not answer";
  }
  ~Running() {
    service_->Stop();
    thread_.join();
  }
  int port() const { return port_; }
  httplib::Client Client(int timeout_s = 10) const {
    httplib::Client c((tls_ ? "https://127.0.0.1:" : "http://127.0.0.1:") + std::to_string(port_));
    if (tls_) c.enable_server_certificate_verification(false);  // self-signed in the tests
    c.set_connection_timeout(timeout_s, 0);
    c.set_read_timeout(timeout_s, 0);
    c.set_write_timeout(timeout_s, 0);
    return c;
  }
  Json Health() const {
    auto r = Client(2).Get("/healthz");
    EXPECT_TRUE(r && r->status == 200) << "healthz did not answer within 2 s: " << httplib::to_string(r.error());
    return r ? Json::parse(r->body) : Json();
  }
  double Metric(const std::string& name) const {
    auto r = Client().Get("/metrics");
    if (!r) return -1;
    std::istringstream in(r->body);
    for (std::string line; std::getline(in, line);)
      if (line.rfind(name + " ", 0) == 0) return std::stod(line.substr(name.size() + 1));
    return -1;
  }

 private:
  bool tls_ = false;
  std::unique_ptr<Service> service_;
  std::thread thread_;
  int port_ = 0;
};

// A raw loopback socket, for requests httplib's client would not send.
int Connect(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_port = htons(std::uint16_t(port));
  sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa), 0);
  timeval tv{5, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  return fd;
}

std::string ReadSome(int fd) {
  char buf[4096];
  const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
  return n > 0 ? std::string(buf, std::size_t(n)) : std::string();
}

class ServiceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string((fs::temp_directory_path() / ("mvkp_serve_test_" + std::to_string(::getpid()))).string());
    fs::create_directories(*dir_);
    const std::string db = *dir_ + "/base.db";
    TargetStore store = TargetStore::Create(db);
    for (const char* id : {"starry", "coffee"}) {
      const std::string path = SamplePath(std::string(id == std::string("starry") ? "starry_night" : id) + ".jpg");
      TargetInfo info;
      info.id = id;
      info.title = id;
      store.Add(MakeTargetRecord(info, FileBytes(path), testing::Sample(fs::path(path).filename()), DbTrainDefaults(),
                                 path));
    }
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  // A fresh copy of the two-exhibit database.
  std::string CopyDb(const std::string& name) {
    const std::string db = *dir_ + "/" + name + ".db";
    fs::remove(db);
    fs::copy_file(*dir_ + "/base.db", db);
    return db;
  }
  ServiceOptions Options(const std::string& db) {
    ServiceOptions o;
    o.db = db;
    o.admin_token = kToken;
    o.watch_s = 0.1;
    return o;
  }
  static httplib::Headers Admin() { return {{"Authorization", std::string("Bearer ") + kToken}}; }
  static std::string StarryJpeg() {
    std::vector<std::uint8_t> b;
    cv::imencode(".jpg", testing::Sample("starry_night.jpg"), b);
    return {b.begin(), b.end()};
  }
  static std::string Deep(int levels) {
    std::string s;
    for (int i = 0; i < levels; ++i) s += "{\"a\":";
    return s + "1" + std::string(std::size_t(levels), '}');
  }
  // No answer may name the database file or carry internal detail.
  void ExpectClean(const httplib::Result& r, const std::string& db) {
    ASSERT_TRUE(r);
    EXPECT_EQ(r->body.find(db), std::string::npos) << r->body;
    EXPECT_EQ(r->body.find(".db"), std::string::npos) << r->body;
  }
  static std::string* dir_;
};
std::string* ServiceTest::dir_ = nullptr;

TEST_F(ServiceTest, RecognisesAndListsAsBefore) {
  Running s(Options(CopyDb("plain")));
  auto c = s.Client();
  auto r = c.Post("/api/recognize", StarryJpeg(), "image/jpeg");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  const Json j = Json::parse(r->body);
  ASSERT_FALSE(j["found"].empty());
  EXPECT_EQ(j["found"][0]["id"], "starry");
  r = c.Get("/api/exhibits");
  ASSERT_TRUE(r && r->status == 200);
  EXPECT_EQ(Json::parse(r->body)["exhibits"].size(), 2u);
  EXPECT_EQ(s.Health()["status"], "ok");
}

// Finding 1: deeply nested JSON crashed the server, and kept crashing it.
TEST_F(ServiceTest, DeepJsonIsRefusedAndDeepStoredMetaDoesNotCrash) {
  const std::string db = CopyDb("deep");
  // A row written before the limits existed (100 000 levels, as in the report).
  Sql(db, "UPDATE targets SET meta = ? WHERE id = 'coffee'", Deep(100000));
  Running s(Options(db));
  auto c = s.Client();
  auto r = c.Get("/api/exhibits");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);
  const Json list = Json::parse(r->body);  // kept alive: the loop walks into it
  for (const auto& e : list["exhibits"]) EXPECT_TRUE(e["meta"].is_object());
  r = c.Get("/api/exhibits/coffee");
  ASSERT_TRUE(r && r->status == 200);
  EXPECT_EQ(Json::parse(r->body)["meta"], Json::object());
  // A PUT of the same depth, and one just over the limit.
  r = c.Put("/api/exhibits/starry", Admin(), "{\"meta\": " + Deep(100000) + "}", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400) << r->body;
  r = c.Put("/api/exhibits/starry", Admin(), "{\"meta\": " + Deep(20) + "}", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("nested deeper"), std::string::npos) << r->body;
  ExpectClean(r, db);
  // An add with deep meta is refused before any training.
  httplib::MultipartFormDataItems add = {{"image", StarryJpeg(), "s.jpg", "image/jpeg"},
                                         {"id", "deep", "", ""},
                                         {"meta", Deep(1000), "", ""}};
  r = c.Post("/api/exhibits", Admin(), add);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400) << r->body;
  EXPECT_EQ(s.Metric("mvkp_trainings_total"), 0);
  EXPECT_EQ(s.Health()["status"], "ok");
  EXPECT_TRUE(TargetStore::Open(db).Get("starry", false).info.meta == "{}");
}

// Finding 3: a second server silently shared the port.
TEST_F(ServiceTest, APortInUseIsAnError) {
  const std::string db = CopyDb("port");
  Running s(Options(db));
  ServiceOptions o = Options(db);
  o.port = s.port();
  o.log = [](const std::string&) {};
  Service second(o);
  try {
    second.Bind();
    FAIL() << "a second service bound port " << s.port();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kIo);
    EXPECT_NE(std::string(e.what()).find("in use"), std::string::npos) << e.what();
  }
  EXPECT_EQ(s.Health()["status"], "ok");
}

// Finding 4: one corrupt row stopped the service from starting; a failing
// reload went unseen.
TEST_F(ServiceTest, ADamagedExhibitIsSkippedAndFailingReloadsAreReported) {
  const std::string db = CopyDb("corrupt");
  Sql(db, "UPDATE targets SET model = ? WHERE id = 'coffee'", std::string(1, '\0'), /*blob=*/true);
  Running s(Options(db));
  Json h = s.Health();
  EXPECT_EQ(h["status"], "degraded");
  ASSERT_EQ(h["skipped"].size(), 1u);
  EXPECT_EQ(h["skipped"][0]["id"], "coffee");
  EXPECT_EQ(h["exhibits"], 1);
  EXPECT_EQ(s.Metric("mvkp_exhibits_skipped"), 1);
  auto r = s.Client().Post("/api/recognize", StarryJpeg(), "image/jpeg");
  ASSERT_TRUE(r && r->status == 200);
  EXPECT_EQ(Json::parse(r->body)["found"][0]["id"], "starry");

  // A database this build cannot read any more: the reload fails, the
  // service keeps serving what it has and says so.
  Sql(db, "PRAGMA user_version = 99");
  bool seen = false;
  for (int i = 0; i < 100 && !seen; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    h = s.Health();
    seen = h.contains("reload") && h["reload"]["ok"] == false;
  }
  ASSERT_TRUE(seen) << h.dump();
  EXPECT_EQ(h["status"], "degraded");
  EXPECT_NE(h["reload"]["error"].get<std::string>().find("newer"), std::string::npos) << h.dump();
  EXPECT_EQ(s.Metric("mvkp_reload_failing"), 1);
  r = s.Client().Post("/api/recognize", StarryJpeg(), "image/jpeg");
  ASSERT_TRUE(r && r->status == 200);
  // Repaired: the next poll reloads and the report clears.
  Sql(db, "PRAGMA user_version = " + std::to_string(kTargetStoreSchemaVersion));
  Sql(db, "UPDATE targets SET title = 'Coffee' WHERE id = 'coffee'");
  for (int i = 0; i < 100 && h.contains("reload"); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    h = s.Health();
  }
  EXPECT_FALSE(h.contains("reload")) << h.dump();
  EXPECT_EQ(s.Metric("mvkp_reload_failing"), 0);
}

// Finding 5: stored images above the pixel limit made quality answer 500.
TEST_F(ServiceTest, QualityOfAStoredImageAboveThePixelLimitIsAssessedReduced) {
  ServiceOptions o = Options(CopyDb("pixels"));
  o.max_pixels = 50'000;  // starry_night.jpg is 400x319
  Running s(o);
  auto r = s.Client(600).Get("/api/exhibits/starry/quality", Admin());  // ~80 s under ASan
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_TRUE(Json::parse(r->body)["score"].is_number());
  r = s.Client().Get("/api/exhibits/starry/image?thumb=100");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
}

// Issue 20: the database as a whole, for the admin page: scores (cached by
// added_at, so the second request assesses nothing) and look-alike pairs.
TEST_F(ServiceTest, DatabaseQualityListsScoresAndLookalikesAndCachesScores) {
  const std::string db = CopyDb("dbquality");
  Running s(Options(db));
  auto r = s.Client().Get("/api/admin/quality");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  r = s.Client(600).Get("/api/admin/quality", Admin());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  ExpectClean(r, db);
  const Json first = Json::parse(r->body);
  ASSERT_EQ(first["exhibits"].size(), 2u);
  EXPECT_EQ(first["assessed_now"], 2);
  EXPECT_TRUE(first["lookalikes"].empty()) << first["lookalikes"];  // starry night and coffee differ
  for (const Json& e : first["exhibits"]) {
    EXPECT_TRUE(e["quality"]["score"].is_number()) << e;
    EXPECT_GT(e["quality"]["stable_points"], 0);
  }
  // The per-exhibit route shares the cache.
  r = s.Client().Get("/api/exhibits/coffee/quality", Admin());
  ASSERT_TRUE(r && r->status == 200);
  EXPECT_EQ(Json::parse(r->body)["cached"], true);
  r = s.Client(600).Get("/api/admin/quality", Admin());
  ASSERT_TRUE(r && r->status == 200);
  const Json second = Json::parse(r->body);
  EXPECT_EQ(second["assessed_now"], 0);
  for (std::size_t i = 0; i < 2; ++i)
    EXPECT_EQ(second["exhibits"][i]["quality"]["score"], first["exhibits"][i]["quality"]["score"]);
}

// Findings 6 and 7, and 9's "refused only after 2 s of training".
TEST_F(ServiceTest, IdsAndLinksFollowTheRulesBeforeAnyTraining) {
  const std::string db = CopyDb("ids");
  Running s(Options(db));
  auto c = s.Client();
  for (const std::string id : {"..", ".", "a b", "bidi\xe2\x80\xaemoc", "caf\xc3\xa9"}) {
    httplib::MultipartFormDataItems add = {{"image", StarryJpeg(), "s.jpg", "image/jpeg"}, {"id", id, "", ""}};
    auto r = c.Post("/api/exhibits", Admin(), add);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400) << id << ": " << r->body;
    ExpectClean(r, db);
  }
  httplib::MultipartFormDataItems js = {{"image", StarryJpeg(), "s.jpg", "image/jpeg"},
                                        {"id", "js", "", ""},
                                        {"url", "javascript:alert(1)", "", ""}};
  auto r = c.Post("/api/exhibits", Admin(), js);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("http"), std::string::npos) << r->body;
  r = c.Put("/api/exhibits/starry", Admin(), R"J({"url": "javascript:alert(1)"})J", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(s.Metric("mvkp_trainings_total"), 0);
  r = c.Put("/api/exhibits/starry", Admin(), R"({"url": "https://example.org/starry"})", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(TargetStore::Open(db).Get("starry", false).info.url, "https://example.org/starry");
}

// Finding 9: PUT accepted unknown fields, a 5 MB title, and ignored id.
TEST_F(ServiceTest, PutTakesOnlyKnownFieldsOfBoundedSize) {
  const std::string db = CopyDb("put");
  Running s(Options(db));
  auto c = s.Client();
  auto r = c.Put("/api/exhibits/starry", Admin(), R"({"titel": "typo"})", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("unknown field 'titel'"), std::string::npos) << r->body;
  r = c.Put("/api/exhibits/starry", Admin(), Json{{"title", std::string(5 << 20, 't')}}.dump(), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  r = c.Put("/api/exhibits/starry", Admin(), Json{{"title", std::string(2000, 't')}}.dump(), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("at most 1000"), std::string::npos) << r->body;
  ExpectClean(r, db);
  r = c.Put("/api/exhibits/starry", Admin(), R"({"id": "other", "title": "x"})", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  r = c.Put("/api/exhibits/starry", Admin(), R"({"id": "starry", "title": "The Starry Night"})", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(TargetStore::Open(db).Get("starry", false).info.title, "The Starry Night");
}

// Finding 9: no limit on token guesses.
TEST_F(ServiceTest, WrongTokensAreSlowedDown) {
  ServiceOptions o = Options(CopyDb("tokens"));
  o.token_failures_before_delay = 3;
  Running s(o);
  auto c = s.Client();
  const httplib::Headers wrong = {{"Authorization", "Bearer wrong-wrong-wrong-wrong"}};
  for (int i = 0; i < 3; ++i) {
    auto r = c.Get("/api/admin/check", wrong);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 401);
  }
  auto r = c.Get("/api/admin/check", wrong);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 429);
  EXPECT_FALSE(r->get_header_value("Retry-After").empty());
  // While blocked, even the right token waits: guesses cannot be tested.
  r = c.Get("/api/admin/check", Admin());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 429);
  EXPECT_GE(s.Metric("mvkp_admin_token_failures_total"), 3);
  EXPECT_EQ(s.Health()["status"], "ok");
}

// Finding 10: 404 for a wrong method, a 10 s wait for a body without length.
TEST_F(ServiceTest, WrongMethodsGet405AndBodiesWithoutLengthGet411) {
  Running s(Options(CopyDb("methods")));
  auto c = s.Client();
  auto r = c.Get("/api/recognize");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 405);
  EXPECT_EQ(r->get_header_value("Allow"), "POST");
  r = c.Delete("/api/exhibits");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 405);
  EXPECT_EQ(r->get_header_value("Allow"), "GET, HEAD, POST");
  r = c.Post("/api/exhibits/starry", "{}", "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 405);
  r = c.Get("/api/nothing");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 404);
  // No Content-Length: the answer comes at once (the socket waits at most 5 s).
  const int fd = Connect(s.port());
  const std::string req = "POST /api/recognize HTTP/1.1\r\nHost: x\r\nContent-Type: image/jpeg\r\n\r\n";
  ASSERT_EQ(::send(fd, req.data(), req.size(), 0), ssize_t(req.size()));
  const std::string answer = ReadSome(fd);
  ::close(fd);
  EXPECT_EQ(answer.rfind("HTTP/1.1 411", 0), 0u) << answer;
}

// Finding 8: every thumbnail decoded the full original.
TEST_F(ServiceTest, ThumbnailsAreCached) {
  Running s(Options(CopyDb("thumbs")));
  auto c = s.Client();
  auto a = c.Get("/api/exhibits/starry/image?thumb=96");
  auto b = c.Get("/api/exhibits/starry/image?thumb=96");
  ASSERT_TRUE(a && b);
  ASSERT_EQ(a->status, 200);
  ASSERT_EQ(b->status, 200);
  EXPECT_EQ(a->body, b->body);
  EXPECT_EQ(s.Metric("mvkp_thumb_cache_misses_total"), 1);
  EXPECT_EQ(s.Metric("mvkp_thumb_cache_hits_total"), 1);
  const cv::Mat t = cv::imdecode(std::vector<std::uint8_t>(a->body.begin(), a->body.end()), cv::IMREAD_COLOR);
  EXPECT_EQ(std::max(t.cols, t.rows), 96);
}

// Finding 2: two slow sockets froze the whole server.
TEST_F(ServiceTest, SlowClientsNeitherStarveOthersNorStayLong) {
  ServiceOptions o = Options(CopyDb("slow"));
  o.io_threads = 16;  // twice the slow sockets below (the default is 32)
  o.read_deadline_s = 1;
  Running s(o);
  std::vector<int> slow;
  for (int i = 0; i < 8; ++i) {
    slow.push_back(Connect(s.port()));
    const std::string part = i % 2 ? "GET /healthz HTTP/1.1\r\nHost: x\r\n" : "POST /api/recognize HTTP/1.1\r\nContent-Length: 100000\r\n\r\nab";
    ::send(slow.back(), part.data(), part.size(), 0);
  }
  // Others are served meanwhile (each call waits at most 2 s).
  for (int i = 0; i < 3; ++i) EXPECT_EQ(s.Health()["status"], "ok");
  auto r = s.Client(2).Post("/api/recognize", StarryJpeg(), "image/jpeg");
  ASSERT_TRUE(r) << "recognition did not answer within 2 s with 8 slow sockets open";
  EXPECT_EQ(r->status, 200);
  // Within the read deadline (1 s) and the watchdog's period, they are cut.
  double cut = 0;
  for (int i = 0; i < 40 && cut < 8; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    cut = s.Metric("mvkp_connections_cut_total");
  }
  EXPECT_GE(cut, 8);
  for (int fd : slow) ::close(fd);
}

// Issue 20: phone photos (12 and 48 MP JPEGs) are accepted with the default
// limits, decoded reduced, and answered in the photo's own pixels.
TEST_F(ServiceTest, PhonePhotosAreAcceptedAndAnsweredInTheirOwnPixels) {
  Running s(Options(CopyDb("phone")));
  auto c = s.Client(60);
  const cv::Mat art = testing::Sample("starry_night.jpg");
  for (const cv::Size size : {cv::Size(4032, 3024), cv::Size(8000, 6000)}) {
    cv::Mat frame;
    cv::resize(testing::Sample("baboon.jpg"), frame, size, 0, 0, cv::INTER_LINEAR);
    // The painting at 40 % of the photo's width, off centre, slightly rotated.
    const double k = 0.4 * size.width / art.cols, a = 0.1;
    const cv::Matx33d H(k * std::cos(a), -k * std::sin(a), 0.3 * size.width, k * std::sin(a), k * std::cos(a),
                        0.2 * size.height, 0, 0, 1);
    cv::Mat warped, mask;
    cv::warpPerspective(art, warped, cv::Mat(H), size, cv::INTER_AREA);
    cv::warpPerspective(cv::Mat(art.size(), CV_8U, cv::Scalar(255)), mask, cv::Mat(H), size, cv::INTER_NEAREST);
    warped.copyTo(frame, mask);
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", frame, jpeg, {cv::IMWRITE_JPEG_QUALITY, 90});
    auto r = c.Post("/api/recognize", std::string(jpeg.begin(), jpeg.end()), "image/jpeg");
    ASSERT_TRUE(r) << size;
    ASSERT_EQ(r->status, 200) << size << " " << r->body;
    const Json j = Json::parse(r->body);
    EXPECT_EQ(j["width"], size.width);
    EXPECT_EQ(j["height"], size.height);
    ASSERT_FALSE(j["found"].empty()) << size;
    EXPECT_EQ(j["found"][0]["id"], "starry");
    const std::vector<cv::Point2d> corners = {{0, 0}, {art.cols - 1.0, 0}, {art.cols - 1.0, art.rows - 1.0}, {0, art.rows - 1.0}};
    const Json& outline = j["found"][0]["outline"];
    ASSERT_EQ(outline.size(), 4u);
    for (int i = 0; i < 4; ++i) {
      const cv::Vec3d t = H * cv::Vec3d(corners[i].x, corners[i].y, 1);
      const double err = std::hypot(outline[i][0].get<double>() - t[0] / t[2], outline[i][1].get<double>() - t[1] / t[2]);
      EXPECT_LT(err, 0.004 * size.width) << size << " corner " << i;  // 16 px at 12 MP, 32 px at 48 MP
    }
  }
  // A GIF or HEIC upload names its format.
  const std::string gif = std::string("GIF89a") + std::string("\x10\x00\x10\x00\x00\x00\x00", 7);
  auto r = c.Post("/api/recognize", gif, "image/gif");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("GIF images are not supported"), std::string::npos) << r->body;
}

// Issue 20: an exhibit's photo is replaced and retrained through the admin
// API; a refused image leaves the old photo and model serving.
TEST_F(ServiceTest, ReplacingAnExhibitsPhotoRetrainsItAndABadOneKeepsTheOld) {
  const std::string db = CopyDb("replace");
  Running s(Options(db));
  auto c = s.Client(120);  // training through HTTP: seconds, a minute under the sanitizers
  std::vector<std::uint8_t> coffee;
  cv::imencode(".jpg", testing::Sample("coffee.jpg"), coffee);
  const std::string coffee_jpeg(coffee.begin(), coffee.end());
  auto r = c.Put("/api/exhibits/starry/image", coffee_jpeg, "image/jpeg");  // no token
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  r = c.Put("/api/exhibits/ghost/image", Admin(), coffee_jpeg, "image/jpeg");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 404);
  const std::string before = TargetStore::Open(db).Get("starry", false).info.added_at;
  r = c.Put("/api/exhibits/starry/image", Admin(), "not an image", "image/jpeg");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400) << r->body;
  ExpectClean(r, db);
  EXPECT_EQ(TargetStore::Open(db).Get("starry", false).info.added_at, before);  // untouched
  r = c.Post("/api/recognize", StarryJpeg(), "image/jpeg");
  ASSERT_TRUE(r && r->status == 200);
  ASSERT_FALSE(Json::parse(r->body)["found"].empty());
  EXPECT_EQ(Json::parse(r->body)["found"][0]["id"], "starry");

  auto thumb_before = c.Get("/api/exhibits/starry/image?thumb=64");
  ASSERT_TRUE(thumb_before && thumb_before->status == 200);
  // The coffee photo shows exhibit "coffee": refused (issue 20: duplicates),
  // unless the admin says so.
  httplib::MultipartFormDataItems form = {{"image", coffee_jpeg, "c.jpg", "image/jpeg"}};
  r = c.Put("/api/exhibits/starry/image", Admin(), form);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 409) << r->body;
  EXPECT_EQ(Json::parse(r->body)["duplicates"][0]["id"], "coffee");
  EXPECT_EQ(TargetStore::Open(db).Get("starry", false).info.added_at, before);  // untouched
  form.push_back({"allow_duplicate", "1", "", ""});
  r = c.Put("/api/exhibits/starry/image", Admin(), form);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  const Json j = Json::parse(r->body);
  EXPECT_EQ(j["id"], "starry");
  EXPECT_EQ(j["title"], "starry");  // metadata stays
  EXPECT_TRUE(j.contains("quality"));
  const TargetRecord stored = TargetStore::Open(db).Get("starry", true);
  EXPECT_EQ(stored.image, coffee);
  auto thumb_after = c.Get("/api/exhibits/starry/image?thumb=64");  // not the cached old one
  ASSERT_TRUE(thumb_after && thumb_after->status == 200);
  EXPECT_NE(thumb_after->body, thumb_before->body);
  // Without exhibit "coffee", the coffee frame is now exhibit "starry".
  r = c.Delete("/api/exhibits/coffee", Admin());
  ASSERT_TRUE(r && r->status == 204);
  r = c.Post("/api/recognize", coffee_jpeg, "image/jpeg");
  ASSERT_TRUE(r && r->status == 200);
  ASSERT_FALSE(Json::parse(r->body)["found"].empty()) << r->body;
  EXPECT_EQ(Json::parse(r->body)["found"][0]["id"], "starry");
  r = c.Get("/api/exhibits/starry/image", Admin());
  ASSERT_TRUE(r && r->status == 200);
  EXPECT_EQ(r->body, coffee_jpeg);
  r = c.Delete("/api/exhibits/starry/image", Admin());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 405);
}

// Issue 20: the museum's name and colours for the visitor page.
TEST_F(ServiceTest, TheSiteFileIsServedAndCheckedWithClearErrors) {
  const std::string db = CopyDb("site");
  {
    Running s(Options(db));  // without --site: defaults, no logo
    auto c = s.Client();
    auto r = c.Get("/api/site");
    ASSERT_TRUE(r && r->status == 200);
    const Json j = Json::parse(r->body);
    EXPECT_EQ(j["name"], "Museum guide");
    EXPECT_TRUE(j["logo"].is_null());
    EXPECT_GE(ContrastRatio(j["colors"]["text"], j["colors"]["background"]), 4.5);
    r = c.Get("/api/site/logo");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 404);
    r = c.Post("/api/site", "{}", "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 405);
  }
  const std::string dir = *dir_ + "/site";
  fs::create_directories(dir);
  std::vector<std::uint8_t> png;
  cv::imencode(".png", cv::Mat(8, 8, CV_8UC3, cv::Scalar(0, 128, 255)), png);
  std::ofstream(dir + "/logo.png", std::ios::binary).write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir + "/" + name) << text;
    return dir + "/" + name;
  };
  ServiceOptions o = Options(db);
  o.site = write("good.json", R"({"name": "Musée Fabre", "intro": "Welcome", "logo": "logo.png",
                                  "colors": {"background": "#FFF", "text": "#1a1a1a", "accent": "#b00020"}})");
  {
    Running s(o);
    auto c = s.Client();
    auto r = c.Get("/api/site");
    ASSERT_TRUE(r && r->status == 200);
    const Json j = Json::parse(r->body);
    EXPECT_EQ(j["name"], "Musée Fabre");
    EXPECT_EQ(j["intro"], "Welcome");
    EXPECT_EQ(j["colors"]["background"], "#ffffff");  // normalised
    EXPECT_EQ(j["colors"]["accent"], "#b00020");
    EXPECT_EQ(j["logo"], "/api/site/logo");
    r = c.Get("/api/site/logo");
    ASSERT_TRUE(r && r->status == 200);
    EXPECT_EQ(r->get_header_value("Content-Type"), "image/png");
    EXPECT_EQ(r->body, std::string(png.begin(), png.end()));
  }
  // Each mistake is an error naming the file and what is wrong, before any exhibit is loaded.
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"{\"name\": \"A\", \"colour\": {}}", "unknown key \"colour\""},
      {"{\"intro\": \"no name\"}", "\"name\" is required"},
      {"{\"name\": \"  \"}", "\"name\" is empty"},
      {"{\"name\": 5}", "\"name\" must be a string"},
      {"{\"name\": \"A\", \"colors\": {\"text\": \"red\"}}", "colors.text must be \"#rgb\" or \"#rrggbb\""},
      {"{\"name\": \"A\", \"colors\": {\"link\": \"#000\"}}", "unknown colour \"link\""},
      {"{\"name\": \"A\", \"colors\": {\"text\": \"#777\", \"background\": \"#888\"}}", "below 4.5:1"},
      {"{\"name\": \"A\", \"logo\": \"missing.png\"}", "no such file"},
      {"{\"name\": \"A\", \"logo\": \"good.json\"}", "not a PNG or JPEG"},
      {"{\"name\": \"A\"", "site"},
      {"[1]", "must be a JSON object"},
  };
  for (std::size_t i = 0; i < bad.size(); ++i) {
    o.site = write("bad" + std::to_string(i) + ".json", bad[i].first);
    try {
      Service service(o);
      ADD_FAILURE() << "accepted " << bad[i].first;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
      EXPECT_NE(std::string(e.what()).find(bad[i].second), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(o.site), std::string::npos) << e.what();
    }
  }
  o.site = dir + "/absent.json";
  EXPECT_THROW(Service{o}, Error);
}

// A self-signed certificate and key for 127.0.0.1 (openssl, as the
// documentation tells museums to make one).
std::pair<std::string, std::string> MakeCertificate(const std::string& dir, const std::string& name) {
  const std::string cert = dir + "/" + name + ".crt", key = dir + "/" + name + ".key";
  const std::string cmd = "openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 -subj /CN=127.0.0.1"
                          " -addext subjectAltName=IP:127.0.0.1 -keyout '" + key + "' -out '" + cert + "' 2>/dev/null";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  return {cert, key};
}

TEST_F(ServiceTest, HttpsServesTheSameRoutesAndLimits) {
  const std::string dir = *dir_ + "/tls";
  fs::create_directories(dir);
  const auto [cert, key] = MakeCertificate(dir, "a");
  ServiceOptions o = Options(CopyDb("https"));
  o.cert = cert;
  o.key = key;
  o.read_deadline_s = 1;
  o.timeout_s = 60;  // so that only the deadline can cut the silent sockets below
  Running s(o);
  auto c = s.Client();
  auto r = c.Post("/api/recognize", StarryJpeg(), "image/jpeg");
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(Json::parse(r->body)["found"][0]["id"], "starry");
  r = c.Get("/");
  ASSERT_TRUE(r && r->status == 200);
  EXPECT_NE(r->body.find("/ui.js"), std::string::npos);
  EXPECT_FALSE(r->get_header_value("Content-Security-Policy").empty());
  r = c.Get("/sw.js");
  ASSERT_TRUE(r && r->status == 200);
  r = c.Delete("/api/recognize");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 405);
  r = c.Get("/api/admin/check", {{"Authorization", "Bearer wrong-token-of-16-chars"}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  r = c.Get("/api/admin/check", Admin());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 204);
  // Plain HTTP to the HTTPS port gets no HTTP answer.
  httplib::Client plain("127.0.0.1", s.port());
  plain.set_read_timeout(5, 0);
  auto p = plain.Get("/healthz");
  EXPECT_TRUE(!p || p->status != 200);
  // Sockets that never start the TLS handshake are cut by the read deadline.
  std::vector<int> silent;
  for (int i = 0; i < 4; ++i) silent.push_back(Connect(s.port()));
  double cut = 0;
  for (int i = 0; i < 60 && cut < 4; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    cut = s.Metric("mvkp_connections_cut_total");
  }
  EXPECT_GE(cut, 4);
  // At most a TLS alert, never an HTTP answer.
  for (int fd : silent) EXPECT_EQ(ReadSome(fd).find("HTTP/"), std::string::npos);
  for (int fd : silent) ::close(fd);
  EXPECT_EQ(s.Health()["status"], "ok");
}

TEST_F(ServiceTest, AMissingOrBadCertificateIsAClearError) {
  const std::string dir = *dir_ + "/badtls";
  fs::create_directories(dir);
  const auto [cert, key] = MakeCertificate(dir, "a");
  const auto [cert2, key2] = MakeCertificate(dir, "b");
  std::ofstream(dir + "/junk.pem") << "-----BEGIN CERTIFICATE-----\nnot base64\n-----END CERTIFICATE-----\n";
  ServiceOptions o = Options(CopyDb("badtls"));
  auto expect = [&](const std::string& c, const std::string& k, ErrorCode code, const std::string& says) {
    o.cert = c;
    o.key = k;
    try {
      Service service(o);
      ADD_FAILURE() << "accepted cert " << c << " key " << k;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), code) << e.what();
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  expect(dir + "/none.crt", key, ErrorCode::kIo, dir + "/none.crt: no such file");
  expect(cert, dir + "/none.key", ErrorCode::kIo, dir + "/none.key: no such file");
  expect(dir + "/junk.pem", key, ErrorCode::kInvalidArgument, "certificate " + dir + "/junk.pem is not a PEM certificate");
  expect(key, key, ErrorCode::kInvalidArgument, "is not a PEM certificate");
  expect(cert, cert, ErrorCode::kInvalidArgument, "private key " + cert + " is not");
  expect(cert, key2, ErrorCode::kInvalidArgument, "private key " + key2);
  expect(cert, "", ErrorCode::kInvalidArgument, "both a certificate and its private key");
  o.cert = cert2;
  o.key = key2;
  EXPECT_NO_THROW(Service{o});
}

// Issue 20: an exhibit added twice (exactly, or cropped and brightened)
// makes both unrecognisable, so the admin API refuses it with 409 and names
// the exhibit it shows; allow_duplicate=1 adds it on purpose.
TEST_F(ServiceTest, AddingAPhotoOfAnExistingExhibitIsRefusedWithItsName) {
  const std::string db = CopyDb("duplicate");
  Running s(Options(db));
  // (each add trains a target: minutes under the sanitizers on a loaded machine)
  auto c = s.Client(180);
  const cv::Mat starry = testing::Sample("starry_night.jpg");
  cv::Mat crop = starry(cv::Rect(starry.cols / 10, starry.rows / 8, starry.cols * 3 / 4, starry.rows * 3 / 4)).clone();
  crop.convertTo(crop, -1, 1.3, 20);
  std::vector<std::uint8_t> crop_jpeg;
  cv::imencode(".jpg", crop, crop_jpeg, {cv::IMWRITE_JPEG_QUALITY, 80});
  for (const std::string& img : {StarryJpeg(), std::string(crop_jpeg.begin(), crop_jpeg.end())}) {
    httplib::MultipartFormDataItems add = {{"image", img, "s.jpg", "image/jpeg"}, {"id", "starry-2", "", ""}};
    auto r = c.Post("/api/exhibits", Admin(), add);
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 409) << r->body;
    const Json j = Json::parse(r->body);
    ASSERT_EQ(j["duplicates"].size(), 1u) << r->body;
    EXPECT_EQ(j["duplicates"][0]["id"], "starry");
    EXPECT_NE(j["error"].get<std::string>().find("allow_duplicate"), std::string::npos);
  }
  EXPECT_FALSE(TargetStore::Open(db).Contains("starry-2"));
  // A distinct picture is added without a word.
  std::vector<std::uint8_t> fruits;
  cv::imencode(".jpg", testing::Sample("fruits.jpg"), fruits);
  httplib::MultipartFormDataItems distinct = {{"image", std::string(fruits.begin(), fruits.end()), "f.jpg", "image/jpeg"},
                                              {"id", "fruits", "", ""}};
  auto r = c.Post("/api/exhibits", Admin(), distinct);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 201) << r->body;
  httplib::MultipartFormDataItems forced = {{"image", StarryJpeg(), "s.jpg", "image/jpeg"},
                                            {"id", "starry-2", "", ""},
                                            {"allow_duplicate", "1", "", ""}};
  r = c.Post("/api/exhibits", Admin(), forced);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 201) << r->body;
  EXPECT_TRUE(TargetStore::Open(db).Contains("starry-2"));
}

// Issue 20: several exhibits at once. `prev` lists what the client saw last
// time; the service follows those and keeps looking for others.
struct Placed {
  std::string id;
  cv::Rect box;  // where the exhibit's image sits in the frame
};

// starry_night.jpg and coffee.jpg side by side on a noisy grey wall, each
// 340 px wide; `which` chooses the ones pasted.
cv::Mat TwoExhibits(const std::vector<std::string>& which, std::vector<Placed>* placed) {
  cv::Mat frame(400, 800, CV_8UC1);
  cv::randn(frame, 110, 12);
  const std::vector<std::pair<std::string, std::string>> all = {{"starry", "starry_night.jpg"}, {"coffee", "coffee.jpg"}};
  for (std::size_t k = 0; k < all.size(); ++k) {
    if (std::find(which.begin(), which.end(), all[k].first) == which.end()) continue;
    const cv::Mat img = testing::Sample(all[k].second);
    cv::Mat small;
    const double s = 340.0 / img.cols;
    cv::resize(img, small, cv::Size(), s, s, cv::INTER_AREA);
    const cv::Rect box(30 + int(k) * 400, 40, small.cols, small.rows);
    small.copyTo(frame(box));
    if (placed) placed->push_back({all[k].first, box});
  }
  return frame;
}

std::string Jpeg(const cv::Mat& m) {
  std::vector<std::uint8_t> b;
  cv::imencode(".jpg", m, b, {cv::IMWRITE_JPEG_QUALITY, 92});
  return {b.begin(), b.end()};
}

// Mean distance (px) of an answer's outline from the placed image's corners.
double OutlineError(const Json& found, const cv::Rect& box) {
  const double x0 = box.x, y0 = box.y, x1 = box.x + box.width - 1., y1 = box.y + box.height - 1.;
  const std::vector<cv::Point2d> truth = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  double e = 0;
  for (int k = 0; k < 4; ++k)
    e += cv::norm(cv::Point2d(found["outline"][k][0].get<double>(), found["outline"][k][1].get<double>()) - truth[k]);
  return e / 4;
}

// The answer's exhibit ids, sorted, each with its outline checked (< 4 px).
std::vector<std::string> FoundIds(const httplib::Result& r, const std::vector<Placed>& placed) {
  std::vector<std::string> ids;
  EXPECT_TRUE(r);
  if (!r) return ids;
  EXPECT_EQ(r->status, 200) << r->body;
  if (r->status != 200) return ids;
  const Json j = Json::parse(r->body);
  for (const Json& f : j["found"]) {
    ids.push_back(f["id"]);
    const auto p = std::find_if(placed.begin(), placed.end(), [&](const Placed& x) { return x.id == f["id"]; });
    if (p == placed.end()) ADD_FAILURE() << "reported an exhibit that is not in view: " << f["id"];
    else EXPECT_LT(OutlineError(f, p->box), 4.0) << f.dump();
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

TEST_F(ServiceTest, PrevListsAreFollowedAndOthersStillFound) {
  Running s(Options(CopyDb("prev")));
  auto c = s.Client();
  std::vector<Placed> both, starry;
  const std::string two = Jpeg(TwoExhibits({"starry", "coffee"}, &both));
  const std::string one = Jpeg(TwoExhibits({"starry"}, &starry));
  const std::vector<std::string> kBoth = {"coffee", "starry"};
  // Both in view, none known yet.
  EXPECT_EQ(FoundIds(c.Post("/api/recognize", two, "image/jpeg"), both), kBoth);
  // Both known: both followed.
  EXPECT_EQ(FoundIds(c.Post("/api/recognize?prev=starry,coffee", two, "image/jpeg"), both), kBoth);
  // One known (a single id, as before the list), a new one appears: found too.
  EXPECT_EQ(FoundIds(c.Post("/api/recognize?prev=starry", two, "image/jpeg"), both), kBoth);
  // A known one has left the view: its focused check runs, and reports nothing.
  auto r = c.Post("/api/recognize?prev=coffee,starry", one, "image/jpeg");
  EXPECT_EQ(FoundIds(r, starry), std::vector<std::string>{"starry"});
  ASSERT_TRUE(r && r->status == 200);
  EXPECT_EQ(Json::parse(r->body)["mode"], "full+focus");
  // Repeated parameters, duplicates and ids no longer in the database are fine.
  EXPECT_EQ(FoundIds(c.Post("/api/recognize?prev=starry&prev=coffee,starry,gone.2019", two, "image/jpeg"), both), kBoth);
  // Empty: no prev.
  EXPECT_EQ(FoundIds(c.Post("/api/recognize?prev=", two, "image/jpeg"), both), kBoth);
}

TEST_F(ServiceTest, MalformedPrevListsAre400) {
  Running s(Options(CopyDb("badprev")));
  auto c = s.Client();
  std::string many;
  for (int i = 0; i < 21; ++i) many += (i ? "," : "") + std::string("x") + std::to_string(i);
  std::string twenty;
  for (int i = 0; i < 20; ++i) twenty += (i ? "," : "") + std::string("x") + std::to_string(i);
  const std::string body = StarryJpeg();
  const std::vector<std::string> bad = {"starry,", ",starry", "starry,,coffee", ",", "starry%01", "%FF%FE",
                                        "x" + std::string(300, 'y'), many};
  for (const std::string& q : bad) {
    auto r = c.Post("/api/recognize?prev=" + q, body, "image/jpeg");
    ASSERT_TRUE(r) << q;
    EXPECT_EQ(r->status, 400) << q << ": " << r->body;
    EXPECT_NE(r->body.find("prev"), std::string::npos) << r->body;
  }
  // The cap itself is fine.
  auto r = c.Post("/api/recognize?prev=" + twenty, body, "image/jpeg");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(s.Health()["status"], "ok");
}

}  // namespace
}  // namespace mvkp::serve
