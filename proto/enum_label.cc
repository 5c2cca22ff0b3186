#include "proto/enum_label.h"

#include <string_view>

namespace forestmap {

std::string EnumLabel(const google::protobuf::EnumDescriptor& descriptor, int value) {
  const google::protobuf::EnumValueDescriptor* found = descriptor.FindValueByNumber(value);
  if (found == nullptr) return std::to_string(value);
  constexpr std::string_view kZeroSuffix = "UNSPECIFIED";
  const google::protobuf::EnumValueDescriptor* zero = descriptor.FindValueByNumber(0);
  std::string_view prefix = zero != nullptr ? std::string_view(zero->name()) : "";
  prefix = prefix.ends_with(kZeroSuffix) ? prefix.substr(0, prefix.size() - kZeroSuffix.size())
                                         : std::string_view();
  const std::string& name = found->name();
  return std::string_view(name).starts_with(prefix) ? name.substr(prefix.size()) : name;
}

}  // namespace forestmap
