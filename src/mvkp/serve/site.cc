#include "mvkp/serve/site.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>

#include "mvkp/core/atomic_file.h"
#include "mvkp/core/error.h"
#include "mvkp/db/json_limits.h"

namespace mvkp::serve {
namespace {

constexpr std::size_t kMaxName = 100, kMaxIntro = 2000, kMaxLogo = 1 << 20;

// "#rgb" or "#rrggbb" -> "#rrggbb" (lower case), or "" when it is neither.
std::string NormaliseColour(std::string c) {
  for (char& ch : c) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  if (c.size() == 4 && c[0] == '#') c = std::string{'#', c[1], c[1], c[2], c[2], c[3], c[3]};
  if (c.size() != 7 || c[0] != '#') return "";
  for (std::size_t i = 1; i < 7; ++i)
    if (!std::isxdigit(static_cast<unsigned char>(c[i]))) return "";
  return c;
}

double Luminance(const std::string& c) {
  double l[3];
  for (int i = 0; i < 3; ++i) {
    const double v = std::stoi(c.substr(1 + 2 * i, 2), nullptr, 16) / 255.0;
    l[i] = v <= 0.03928 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
  }
  return 0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2];
}

}  // namespace

double ContrastRatio(const std::string& a, const std::string& b) {
  const double la = Luminance(a), lb = Luminance(b);
  return (std::max(la, lb) + 0.05) / (std::min(la, lb) + 0.05);
}

nlohmann::json Site::ToJson() const {
  return {{"name", name},
          {"intro", intro},
          {"colors", {{"background", background}, {"text", text}, {"accent", accent}}},
          {"logo", logo.empty() ? nlohmann::json(nullptr) : nlohmann::json("/api/site/logo")}};
}

Site ParseSite(const std::string& text, const std::string& what, const std::string& dir) {
  JsonLimits lim;
  lim.max_depth = 4;
  lim.max_bytes = 64 << 10;
  const nlohmann::json j = ParseJsonLimited(text, lim, what);
  auto bad = [&](const std::string& msg) { throw Error(ErrorCode::kInvalidArgument, what + ": " + msg); };
  if (!j.is_object()) bad("must be a JSON object with at least \"name\"");
  static const std::set<std::string> kKeys = {"name", "intro", "logo", "colors"};
  for (const auto& [k, v] : j.items())
    if (!kKeys.count(k)) bad("unknown key \"" + k + "\" (keys: name, intro, logo, colors)");
  auto str = [&](const char* k, std::size_t max, bool required) -> std::string {
    if (!j.contains(k)) {
      if (required) bad(std::string("\"") + k + "\" is required");
      return "";
    }
    if (!j[k].is_string()) bad(std::string("\"") + k + "\" must be a string");
    const std::string s = j[k].get<std::string>();
    if (s.size() > max) bad(std::string("\"") + k + "\" is longer than " + std::to_string(max) + " bytes");
    return s;
  };
  Site site;
  site.name = str("name", kMaxName, true);
  if (site.name.find_first_not_of(" \t\r\n") == std::string::npos) bad("\"name\" is empty");
  site.intro = str("intro", kMaxIntro, false);
  if (j.contains("colors")) {
    const auto& c = j["colors"];
    if (!c.is_object()) bad("\"colors\" must be an object with background, text, accent");
    for (const auto& [k, v] : c.items()) {
      std::string* dst = k == "background" ? &site.background : k == "text" ? &site.text : k == "accent" ? &site.accent : nullptr;
      if (!dst) bad("unknown colour \"" + k + "\" (colors: background, text, accent)");
      const std::string n = v.is_string() ? NormaliseColour(v.get<std::string>()) : "";
      if (n.empty()) bad("colors." + k + " must be \"#rgb\" or \"#rrggbb\", not " + v.dump());
      *dst = n;
    }
  }
  const double ratio = ContrastRatio(site.text, site.background);
  if (ratio < 4.5) {
    char b[160];
    std::snprintf(b, sizeof b, "colors.text %s on colors.background %s has a contrast of %.2f:1, below 4.5:1 (WCAG AA)",
                  site.text.c_str(), site.background.c_str(), ratio);
    bad(b);
  }
  const std::string logo = str("logo", 4096, false);
  if (!logo.empty()) {
    const std::filesystem::path p = std::filesystem::path(logo).is_absolute() ? std::filesystem::path(logo)
                                                                               : std::filesystem::path(dir) / logo;
    std::vector<std::uint8_t> bytes;
    try {
      bytes = ReadFileBytes(p.string(), kMaxLogo);
    } catch (const Error& e) {
      bad(std::string("logo: ") + e.what() + (std::string(e.what()).find("too large") != std::string::npos ? " (at most 1 MiB)" : ""));
    }
    const bool png = bytes.size() > 8 && bytes[0] == 0x89 && bytes[1] == 'P' && bytes[2] == 'N' && bytes[3] == 'G';
    const bool jpeg = bytes.size() > 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
    if (!png && !jpeg) bad("logo " + p.string() + " is not a PNG or JPEG image");
    site.logo.assign(bytes.begin(), bytes.end());
    site.logo_type = png ? "image/png" : "image/jpeg";
  }
  return site;
}

Site LoadSite(const std::string& path) {
  const auto bytes = ReadFileBytes(path, 64 << 10);
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return ParseSite(std::string(bytes.begin(), bytes.end()), path, dir.empty() ? "." : dir);
}

}  // namespace mvkp::serve
