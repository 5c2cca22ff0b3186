#pragma once
// The checks of one UploadTrees stream, message by message (server/grpc/upload_stream.cc).

#include <google/protobuf/repeated_ptr_field.h>

#include <cstdint>
#include <string>

#include "forestmap/v1/maps.pb.h"

namespace forestmap::server {

// Checks the messages of one UploadTrees stream, in order, in either layout
// (server/grpc/legacy_layout.h): a header naming a valid map first, then chunks (in the 0.1.0
// layout: later messages repeat the map's name or leave it empty and set no other header field);
// every tree is valid; the tree total stays within the limit. Ids unique across the stream are
// checked by the store as it stages the trees (in constant memory here). Tree indices count
// across the whole stream ("trees[k]" = k-th tree uploaded).
class UploadValidator {
 public:
  explicit UploadValidator(int64_t max_trees) : max_trees_(max_trees) {}

  // Checks the next message and returns its trees (moved out of it).
  google::protobuf::RepeatedPtrField<v1::Tree> Accept(v1::UploadTreesRequest& message);
  // Call when the client has closed the stream; throws if it sent no message.
  void Finish() const;

  const v1::UploadTreesHeader& header() const { return header_; }  // of the first message
  int64_t messages() const { return messages_; }
  int64_t trees() const { return trees_; }

 private:
  void CheckRepeatedHeader(const v1::UploadTreesHeader& repeated, const std::string& where) const;

  int64_t max_trees_;
  v1::UploadTreesHeader header_;
  int64_t messages_ = 0;
  int64_t trees_ = 0;
};

}  // namespace forestmap::server
