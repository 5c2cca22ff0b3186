#pragma once
// Enum values as outputs show them: the value's name without its enum's prefix, "LOCALIZED" for
// RelocalizeResponse.STATUS_LOCALIZED, "OBSERVE" for MapVersion.KIND_OBSERVE. (The API's values
// carry the prefix, as buf lint asks; the CLI, the web page and the Python client kept the short
// names they always printed.) Shared by client and server.

#include <google/protobuf/descriptor.h>

#include <string>

namespace forestmap {

// `value` of `descriptor` by name without the prefix of its zero value <PREFIX>_UNSPECIFIED;
// its number as text when the enum has no such value.
std::string EnumLabel(const google::protobuf::EnumDescriptor& descriptor, int value);

}  // namespace forestmap
