#include "storage/attribute_json.h"

#include <nlohmann/json.hpp>
#include <stdexcept>

namespace forestmap::storage::internal {

std::optional<std::string> EncodeAttributes(const std::map<std::string, std::string>& values,
                                            const std::set<std::string>& nulls) {
  if (values.empty() && nulls.empty()) return std::nullopt;
  nlohmann::json object = values;  // an object of strings (an empty one when there are only nulls)
  if (values.empty()) object = nlohmann::json::object();
  for (const std::string& name : nulls) object[name] = nullptr;
  return object.dump();  // throws json::type_error on invalid UTF-8
}

TreeAttributes DecodeAttributes(const std::string& text) {
  TreeAttributes attributes;
  nlohmann::json object;
  try {
    object = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(e.what());
  }
  if (!object.is_object()) throw std::invalid_argument("not a JSON object");
  for (const auto& [name, value] : object.items()) {
    if (value.is_null()) {
      attributes.nulls.insert(name);
    } else if (value.is_string()) {
      attributes.values.emplace(name, value.get<std::string>());
    } else {
      throw std::invalid_argument("the value of '" + name + "' is neither a string nor null");
    }
  }
  return attributes;
}

}  // namespace forestmap::storage::internal
