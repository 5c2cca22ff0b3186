#include "tests/server/http_get.h"

#include <httplib.h>

namespace forestmap::test {

HttpAnswer HttpGet(const std::string& host, int port, const std::string& path,
                   const std::string& bearer, const HttpHeaders& headers) {
  httplib::Client client(host, port);
  httplib::Headers sent(headers.begin(), headers.end());
  if (!bearer.empty()) sent.emplace("Authorization", "Bearer " + bearer);
  const httplib::Result result = client.Get(path.c_str(), sent);
  HttpAnswer answer;
  if (!result) return answer;
  answer.ok = true;
  answer.status = result->status;
  answer.content_type = result->get_header_value("Content-Type");
  answer.transfer_encoding = result->get_header_value("Transfer-Encoding");
  answer.location = result->get_header_value("Location");
  answer.set_cookie = result->get_header_value("Set-Cookie");
  answer.body = result->body;
  return answer;
}

}  // namespace forestmap::test
