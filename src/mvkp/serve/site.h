// The museum's name, colours, logo and welcome text for the visitor page
// (`mvkp serve --site site.json`), served as GET /api/site.
//
//   {"name": "Musée Fabre",                      required, 1..100 bytes
//    "intro": "Point your phone at a painting.", optional, at most 2000 bytes
//    "logo": "logo.png",                         optional PNG/JPEG file (at most 1 MiB),
//                                                relative to the site file; GET /api/site/logo
//    "colors": {"background": "#102030",        optional, "#rgb" or "#rrggbb":
//               "text": "#ffffff",                 page and header; text on background
//               "accent": "#e0a030"}}              must reach a contrast of 4.5:1 (WCAG AA);
//                                                  accent colours buttons and outlines
// Unknown keys are an error (a typo would otherwise pass unseen).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace mvkp::serve {

struct Site {
  std::string name = "Museum guide";
  std::string intro;
  std::string background = "#14181f";
  std::string text = "#ffffff";
  std::string accent = "#ffcc4d";
  std::string logo;       // the logo file's bytes ("" for none)
  std::string logo_type;  // "image/png" or "image/jpeg"

  // The JSON of GET /api/site (logo: its URL or null).
  nlohmann::json ToJson() const;
};

// Reads and checks a site file; throws Error (kIo: unreadable, kInvalidArgument:
// what is wrong, naming the file and the key).
Site LoadSite(const std::string& path);

// Parses a site description; logo paths are relative to `dir`.
Site ParseSite(const std::string& text, const std::string& what, const std::string& dir);

// WCAG 2 contrast ratio of two "#rrggbb" colours (1..21).
double ContrastRatio(const std::string& a, const std::string& b);

}  // namespace mvkp::serve
