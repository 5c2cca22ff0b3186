#include "server/grpc/list_pages.h"

#include <absl/strings/escaping.h>

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "server/grpc/convert.h"
#include "server/grpc/status.h"
#include "server/grpc/validation.h"

namespace forestmap::server {
namespace {

constexpr std::string_view kTokenFormat = "fm1";  // changes with the layout of the parts

int PageSize(int32_t page_size) {
  if (page_size < 0) {
    throw ValidationError("page_size", " is " + std::to_string(page_size) +
                                           "; it must be >= 0 (0: the default of " +
                                           std::to_string(kDefaultPageSize) + ")");
  }
  if (page_size == 0) return kDefaultPageSize;
  return std::min(static_cast<int>(page_size), kMaxPageSize);
}

// The parts as <length>:<bytes> each, so that any bytes split back, then web-safe base64.
std::string EncodePageToken(const std::vector<std::string>& parts) {
  std::string packed(kTokenFormat);
  for (const std::string& part : parts) packed += std::to_string(part.size()) + ":" + part;
  return absl::WebSafeBase64Escape(packed);
}

bool UnpackToken(std::string_view packed, std::vector<std::string>& parts) {
  if (!packed.starts_with(kTokenFormat)) return false;
  packed.remove_prefix(kTokenFormat.size());
  while (!packed.empty()) {
    size_t length = 0;
    const auto [end, error] = std::from_chars(packed.data(), packed.data() + packed.size(), length);
    if (error != std::errc() || end == packed.data() || *end != ':') return false;
    packed.remove_prefix(static_cast<size_t>(end - packed.data()) + 1);
    if (length > packed.size()) return false;
    parts.emplace_back(packed.substr(0, length));
    packed.remove_prefix(length);
  }
  return true;
}

// The position parts of `token`, whose first parts must equal `scope` (the listing's RPC and
// the arguments that may not change between pages).
std::vector<std::string> DecodePageToken(const std::string& token,
                                         const std::vector<std::string>& scope,
                                         size_t position_parts) {
  std::string packed;
  std::vector<std::string> parts;
  if (!absl::WebSafeBase64Unescape(token, &packed) || !UnpackToken(packed, parts)) {
    throw ValidationError("page_token",
                          " is not a page token of this server; pass the next_page_token of the "
                          "previous page unchanged, or none for the first page");
  }
  if (parts.size() != scope.size() + position_parts ||
      !std::equal(scope.begin(), scope.end(), parts.begin())) {
    throw ValidationError("page_token",
                          " belongs to another listing; keep every argument but page_size and "
                          "page_token as it was for the first page");
  }
  return {parts.begin() + static_cast<std::ptrdiff_t>(scope.size()), parts.end()};
}

int64_t VersionIn(const std::string& text) {
  int64_t version = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), version);
  if (error != std::errc() || end != text.data() + text.size() || version < 0) {
    throw ValidationError("page_token", " is not a page token of this server");
  }
  return version;
}

}  // namespace

v1::ListMapsResponse ListMapsPage(storage::MapStore& store, const Caller& caller,
                                  const v1::ListMapsRequest& request) {
  const int size = PageSize(request.page_size());
  const std::vector<std::string> scope = {"ListMaps"};
  std::string after;  // names are never empty: "" precedes them all
  if (!request.page_token().empty()) after = DecodePageToken(request.page_token(), scope, 1)[0];
  std::vector<storage::MapInfo> maps = store.ListMaps();
  // Bytewise, whatever the database's collation: the order the tokens continue in.
  std::sort(maps.begin(), maps.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  v1::ListMapsResponse response;
  for (const storage::MapInfo& info : maps) {
    if (info.name <= after || !caller.CanRead(info.name)) continue;
    if (response.maps_size() == size) {
      response.set_next_page_token(EncodePageToken({scope[0], response.maps(size - 1).name()}));
      break;
    }
    *response.add_maps() = ToProto(info);
  }
  return response;
}

v1::ListVersionsResponse ListVersionsPage(storage::MapStore& store,
                                          const v1::ListVersionsRequest& request) {
  Validate(request);
  const int size = PageSize(request.page_size());
  const std::vector<std::string> scope = {"ListVersions", request.name(),
                                          std::to_string(request.limit())};
  // The listing is the versions in (after, until]: until is the newest one at the first page.
  int64_t after = 0;
  int64_t until = std::numeric_limits<int64_t>::max();
  std::vector<storage::VersionRecord> records;
  if (request.page_token().empty()) {
    records = store.ListVersions(request.name(), request.limit());
    if (!records.empty()) until = records.back().version;
  } else {
    const std::vector<std::string> position = DecodePageToken(request.page_token(), scope, 2);
    after = VersionIn(position[0]);
    until = VersionIn(position[1]);
    records = store.ListVersions(request.name(), 0);
  }
  v1::ListVersionsResponse response;
  for (const storage::VersionRecord& record : records) {
    if (record.version <= after || record.version > until) continue;
    if (response.versions_size() == size) {
      const int64_t last = response.versions(size - 1).version();
      response.set_next_page_token(EncodePageToken(
          {scope[0], scope[1], scope[2], std::to_string(last), std::to_string(until)}));
      break;
    }
    *response.add_versions() = ToProto(record);
  }
  return response;
}

}  // namespace forestmap::server
