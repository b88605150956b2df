// The museum guide's web client (web/), built into the binary so the guide service
// needs no files at run time.
#pragma once

#include <string_view>

namespace mvkp::serve {

struct WebAsset {
  std::string_view path;          // URL path, e.g. "/app.js"
  std::string_view content_type;
  std::string_view body;
};

// The asset served at `path` ("/" is index.html, "/admin" admin.html), or nullptr.
const WebAsset* FindWebAsset(std::string_view path);

}  // namespace mvkp::serve
