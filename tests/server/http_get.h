#pragma once
// A plain HTTP (or HTTPS) GET for tests, in its own file: httplib.h pulls in <resolv.h>, whose
// `_res` macro breaks Eigen headers included after it.

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
  std::string error;  // why there is no answer (cpp-httplib's error name)
};

using HttpHeaders = std::vector<std::pair<std::string, std::string>>;

// `bearer` non-empty: sent as "Authorization: Bearer <bearer>"; `headers` are sent as given.
HttpAnswer HttpGet(const std::string& host, int port, const std::string& path,
                   const std::string& bearer = "", const HttpHeaders& headers = {});

// PEM files of an HTTPS client: the CA that signed the server's certificate (verified), and
// optionally a client certificate with its key.
struct TlsClientFiles {
  std::string ca;
  std::string cert;
  std::string key;
};

// HttpGet over HTTPS (cpp-httplib on OpenSSL): a failed handshake is no answer. Ignores SIGPIPE
// in the process from then on.
HttpAnswer HttpsGet(const std::string& host, int port, const std::string& path,
                    const TlsClientFiles& tls, const std::string& bearer = "",
                    const HttpHeaders& headers = {});

}  // namespace forestmap::test
