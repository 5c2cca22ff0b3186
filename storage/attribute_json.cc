#include "storage/attribute_json.h"

#include <algorithm>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "storage/map_store.h"

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

std::string EncodeColumnOrder(const std::vector<std::string>& names) {
  if (names.empty()) return {};
  return nlohmann::json(names).dump();  // throws json::type_error on invalid UTF-8
}

std::vector<std::string> DecodeColumnOrder(const std::string& map_name, const std::string& text) {
  if (text.empty()) return {};
  try {
    return nlohmann::json::parse(text).get<std::vector<std::string>>();
  } catch (const nlohmann::json::exception& e) {
    throw StorageError(StorageError::Code::kInternal,
                       "map '" + map_name + "': stored attribute order is damaged: " + e.what());
  }
}

std::vector<std::string> MergeColumnOrder(const std::vector<std::string>& stored,
                                          const std::vector<std::string>& uploaded, bool replace) {
  if (uploaded.empty()) return stored;
  std::vector<std::string> order = replace ? std::vector<std::string>() : stored;
  for (const std::string& name : uploaded) {
    if (std::find(order.begin(), order.end(), name) == order.end()) order.push_back(name);
  }
  return order;
}

}  // namespace forestmap::storage::internal
