#include "mvkp/serve/web_assets.h"

#include <array>

// Each file of web/ is linked in as read-only data (.incbin, as the default
// vocabulary is); the paths come from CMake.
#define MVKP_INCBIN(sym, file)                                  \
  __asm__(".section .rodata\n"                                  \
          ".global " #sym "_begin\n"                            \
          ".type " #sym "_begin, @object\n" #sym "_begin:\n"    \
          ".incbin \"" file "\"\n"                              \
          ".global " #sym "_end\n"                              \
          ".type " #sym "_end, @object\n" #sym "_end:\n"        \
          ".previous\n");                                       \
  extern "C" const char sym##_begin[];                          \
  extern "C" const char sym##_end[]

MVKP_INCBIN(mvkp_web_index, MVKP_WEB_DIR "/index.html");
MVKP_INCBIN(mvkp_web_app, MVKP_WEB_DIR "/app.js");
MVKP_INCBIN(mvkp_web_style, MVKP_WEB_DIR "/style.css");
MVKP_INCBIN(mvkp_web_ui, MVKP_WEB_DIR "/ui.js");
MVKP_INCBIN(mvkp_web_sw, MVKP_WEB_DIR "/sw.js");
MVKP_INCBIN(mvkp_web_admin, MVKP_WEB_DIR "/admin.html");
MVKP_INCBIN(mvkp_web_admin_js, MVKP_WEB_DIR "/admin.js");
MVKP_INCBIN(mvkp_web_admin_css, MVKP_WEB_DIR "/admin.css");

namespace mvkp::serve {
namespace {

std::string_view View(const char* b, const char* e) { return {b, std::size_t(e - b)}; }

}  // namespace

const WebAsset* FindWebAsset(std::string_view path) {
  static const std::array<WebAsset, 8> assets = {{
      {"/index.html", "text/html; charset=utf-8", View(mvkp_web_index_begin, mvkp_web_index_end)},
      {"/app.js", "text/javascript; charset=utf-8", View(mvkp_web_app_begin, mvkp_web_app_end)},
      {"/style.css", "text/css; charset=utf-8", View(mvkp_web_style_begin, mvkp_web_style_end)},
      {"/ui.js", "text/javascript; charset=utf-8", View(mvkp_web_ui_begin, mvkp_web_ui_end)},
      {"/sw.js", "text/javascript; charset=utf-8", View(mvkp_web_sw_begin, mvkp_web_sw_end)},
      {"/admin.html", "text/html; charset=utf-8", View(mvkp_web_admin_begin, mvkp_web_admin_end)},
      {"/admin.js", "text/javascript; charset=utf-8", View(mvkp_web_admin_js_begin, mvkp_web_admin_js_end)},
      {"/admin.css", "text/css; charset=utf-8", View(mvkp_web_admin_css_begin, mvkp_web_admin_css_end)},
  }};
  if (path == "/") path = "/index.html";
  if (path == "/admin" || path == "/admin/") path = "/admin.html";
  for (const auto& a : assets)
    if (a.path == path) return &a;
  return nullptr;
}

}  // namespace mvkp::serve
