#pragma once
// A plain HTTP GET for tests, in its own file: httplib.h pulls in <resolv.h>, whose `_res` macro
// breaks Eigen headers included after it.

#include <string>

namespace forestmap::test {

struct HttpAnswer {
  bool ok = false;  // false: no answer (connection failed)
  int status = 0;   // HTTP status code
  std::string content_type;
  std::string transfer_encoding;  // "chunked" for a streamed answer
  std::string body;
};

// `bearer` non-empty: sent as "Authorization: Bearer <bearer>".
HttpAnswer HttpGet(const std::string& host, int port, const std::string& path,
                   const std::string& bearer = "");

}  // namespace forestmap::test
