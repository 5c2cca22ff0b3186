#include "server/app/exactly_once.h"

#include "storage/token_store.h"

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

std::string Fingerprint(const WriteCall& call) {
  std::string bound;
  for (const std::string* part : {&call.rpc, &call.map, &call.caller, &call.content_digest}) {
    bound += std::to_string(part->size()) + ":" + *part + ";";  // unambiguous concatenation
  }
  return storage::Sha256Hex(bound);
}

std::optional<storage::StoredRequest> FindStoredRequest(storage::MapStore& store,
                                                        const std::string& id,
                                                        std::string_view rpc) {
  std::optional<storage::StoredRequest> stored = store.FindRequest(id);
  if (stored && stored->rpc != rpc) {
    throw ValidationError("request_id", " '" + id + "' was already used for a " + stored->rpc +
                                            " call; use a new id for every write");
  }
  return stored;
}

std::optional<std::string> StoredAnswer(storage::MapStore& store, const WriteCall& call) {
  std::optional<storage::StoredRequest> stored =
      FindStoredRequest(store, call.request_id, call.rpc);
  if (!stored) return std::nullopt;
  // Answers stored before ids were bound carry no fingerprint: bound to the call only.
  if (!stored->fingerprint.empty() && stored->fingerprint != Fingerprint(call)) {
    throw ValidationError("request_id",
                          " '" + call.request_id +
                              "' was used for a different request (another map, caller or "
                              "content); nothing was written: use a new id for every write");
  }
  return std::move(stored->response);
}

}  // namespace forestmap::server
