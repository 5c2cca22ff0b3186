#include "server/grpc/upload_validator.h"

#include "server/app/errors.h"
#include "server/grpc/legacy_layout.h"
#include "server/grpc/validation.h"

namespace forestmap::server {

google::protobuf::RepeatedPtrField<v1::Tree> UploadValidator::Accept(
    v1::UploadTreesRequest& message) {
  const std::string where = " (upload message " + std::to_string(messages_) + ")";
  const bool legacy = HasLegacyFields(message);
  if (legacy && message.part_case() != v1::UploadTreesRequest::PART_NOT_SET) {
    throw ValidationError(message.has_header() ? "header" : "chunk", where + kMixedLayouts);
  }
  google::protobuf::RepeatedPtrField<v1::Tree> trees;
  if (message.has_header()) {
    if (messages_ > 0) {
      throw ValidationError("header", where + ": only the first message of an upload is a header");
    }
    header_ = message.header();
    ValidateMapName(header_.name(), "header.name");
    if (header_.has_boundary()) ValidateBoundary(header_.boundary(), "header.boundary");
    ValidateAttributeColumns(header_.attribute_columns(), "header.attribute_columns");
  } else if (message.has_chunk()) {
    if (messages_ == 0) {
      throw ValidationError("header", " is missing: the first message of an upload names the map");
    }
    trees.Swap(message.mutable_chunk()->mutable_trees());
  } else {  // the 0.1.0 layout: the first message names the map, every message holds trees
    if (messages_ == 0) {
      header_ = LegacyHeader(message);
      ValidateMapName(header_.name(), "name");
    } else {
      CheckRepeatedHeader(LegacyHeader(message), where);
    }
    trees = TakeLegacyTrees(message);
  }
  ++messages_;
  if (trees.size() > max_trees_ - trees_) {
    throw LimitError("trees: the upload exceeds the limit of " + std::to_string(max_trees_) +
                     " trees per stream");
  }
  for (const v1::Tree& tree : trees) ValidateTree(tree, Indexed("trees", trees_++));
  return trees;
}

// A later message of the 0.1.0 layout may repeat the map's name and request id, nothing else.
void UploadValidator::CheckRepeatedHeader(const v1::UploadTreesHeader& repeated,
                                          const std::string& where) const {
  if (!repeated.name().empty() && repeated.name() != header_.name()) {
    throw ValidationError("name", " " + Quoted(repeated.name()) + where +
                                      " differs from the upload's map " + Quoted(header_.name()));
  }
  if (!repeated.request_id().empty() && repeated.request_id() != header_.request_id()) {
    throw ValidationError("request_id", where +
                                            " differs from the first message's; only the "
                                            "first sets it");
  }
  if (repeated.replace() && !header_.replace()) {
    throw ValidationError("replace", where + ": only the first message may set replace");
  }
  if (repeated.create_map() || !repeated.description().empty() || !repeated.crs().empty()) {
    throw ValidationError(repeated.create_map()    ? "create_map"
                          : repeated.crs().empty() ? "description"
                                                   : "crs",
                          where +
                              ": only the first message may set create_map, description "
                              "and crs");
  }
}

void UploadValidator::Finish() const {
  if (messages_ == 0) {
    throw ValidationError("header",
                          " is missing: the upload stream was empty; its first message names the "
                          "map");
  }
}

}  // namespace forestmap::server
