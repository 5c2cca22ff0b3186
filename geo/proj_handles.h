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
  std::string Error() const { return proj_context_errno_string(ctx, proj_context_errno(ctx)); }
  PJ_CONTEXT* ctx;
};

struct PjDeleter {
  void operator()(PJ* pj) const { proj_destroy(pj); }
};
using PjPtr = std::unique_ptr<PJ, PjDeleter>;

}  // namespace forestmap::geo::internal
