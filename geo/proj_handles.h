#pragma once
// PROJ handles for geo/*.cc (private to forestmap_geo: the only code that includes proj.h).

#include <proj.h>

#include <memory>
#include <string>

namespace forestmap::geo::internal {

// A PROJ context of our own: its errors are read here, never logged by PROJ.
struct Context {
  Context() : ctx(proj_context_create()) { proj_log_level(ctx, PJ_LOG_NONE); }
  ~Context() { proj_context_destroy(ctx); }
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  // PROJ's reason for the last failure; PROJ gives none (null) for some, e.g. no transformation
  // between an engineering CRS and WGS84.
  std::string Error() const {
    const char* text = proj_context_errno_string(ctx, proj_context_errno(ctx));
    return text ? text : "no reason given by PROJ";
  }
  PJ_CONTEXT* ctx;
};

struct PjDeleter {
  void operator()(PJ* pj) const { proj_destroy(pj); }
};
using PjPtr = std::unique_ptr<PJ, PjDeleter>;

}  // namespace forestmap::geo::internal
