#include "server/grpc/stream_limits.h"

#include <stdexcept>
#include <string>

namespace forestmap::server {

void StreamLimitOptions::Check() const {
  if (max_streams < 1) throw std::invalid_argument("StreamLimitOptions.max_streams must be >= 1");
  if (max_streams_per_client < 1) {
    throw std::invalid_argument("StreamLimitOptions.max_streams_per_client must be >= 1");
  }
}

std::unique_ptr<StreamLimits::Slot> StreamLimits::TryAcquire(const std::string& peer,
                                                             const char* rpc,
                                                             std::string& refusal) {
  std::lock_guard<std::mutex> lock(mutex_);
  int& mine = per_peer_[peer];
  if (mine >= options_.max_streams_per_client) {
    refusal = std::string(rpc) + ": this client already has " + std::to_string(mine) +
              " upload/export streams open, the limit per client (forestmapd " +
              "--max-streams-per-client " + std::to_string(options_.max_streams_per_client) +
              "); finish one and retry";
  } else if (open_ >= options_.max_streams) {
    refusal = std::string(rpc) + ": the server has " + std::to_string(open_) +
              " upload/export streams open, its limit (forestmapd --max-streams " +
              std::to_string(options_.max_streams) + "); retry later";
  } else {
    ++mine;
    ++open_;
    return std::make_unique<Slot>(*this, peer);
  }
  if (mine == 0) per_peer_.erase(peer);
  return nullptr;
}

void StreamLimits::Release(const std::string& peer) {
  std::lock_guard<std::mutex> lock(mutex_);
  --open_;
  const auto it = per_peer_.find(peer);
  if (it != per_peer_.end() && --it->second <= 0) per_peer_.erase(it);
}

int StreamLimits::open() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return open_;
}

}  // namespace forestmap::server
