#include "server/app/exactly_once.h"

namespace forestmap::server {

void ValidateRequestId(const std::string& id, const std::string& field) {
  if (id.size() > kMaxRequestIdLength) {
    throw ValidationError(field, ": " + std::to_string(id.size()) + " bytes exceed the limit of " +
                                     std::to_string(kMaxRequestIdLength));
  }
  for (size_t i = 0; i < id.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(id[i]);
    if (c < 0x21 || c > 0x7e) {
      throw ValidationError(
          field, ": character " + std::to_string(i + 1) + " is not printable ASCII (0x21..0x7e)");
    }
  }
}

std::optional<std::string> StoredAnswer(storage::MapStore& store, const std::string& id,
                                        std::string_view rpc) {
  std::optional<storage::StoredRequest> stored = store.FindRequest(id);
  if (!stored) return std::nullopt;
  if (stored->rpc != rpc) {
    throw ValidationError("request_id", " '" + id + "' was already used for a " + stored->rpc +
                                            " call; use a new id for every write");
  }
  return std::move(stored->response);
}

}  // namespace forestmap::server
