// apps/progiso/view/view_assets.hpp — the page of `progiso view`, built into the binary.
//
// web/src/ (the page and its script) and the three.js modules it imports (web/node_modules,
// installed by scripts/install-deps.sh from web/package-lock.json) are assembled into the
// executable at build time (.incbin, apps/progiso/CMakeLists.txt), so the command reads no file
// to serve the page and no request can name one.
#pragma once

#include <vector>

#include "view_server.hpp"

namespace progiso::view {

/// Every file of the page, by request path.
[[nodiscard]] std::vector<asset> page_assets();

}  // namespace progiso::view
