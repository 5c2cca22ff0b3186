#pragma once
// A plain HTTP GET for tests, in its own file: httplib.h pulls in <resolv.h>, whose `_res` macro
// breaks Eigen headers included after it.

#include <string>
#include <utility>
#include <vector>

namespace forestmap::test {

struct HttpAnswer {
  bool ok = false;  // false: no answer (connection failed)
  int status = 0;   // HTTP status code
  std::string content_type;
  std::string transfer_encoding;  // "chunked" for a streamed answer
  std::string location;           // of a redirect
  std::string set_cookie;
  std::string body;
};

using HttpHeaders = std::vector<std::pair<std::string, std::string>>;

// `bearer` non-empty: sent as "Authorization: Bearer <bearer>"; `headers` are sent as given.
HttpAnswer HttpGet(const std::string& host, int port, const std::string& path,
                   const std::string& bearer = "", const HttpHeaders& headers = {});

}  // namespace forestmap::test
