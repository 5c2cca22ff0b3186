#pragma once
// A tree's survey columns as stored by both stores: one JSON object, a string per known value and
// null per unknown one ({"Spp": "41", "LI": null}), or SQL NULL when the tree has neither.

#include <map>
#include <optional>
#include <set>
#include <string>

namespace forestmap::storage::internal {

struct TreeAttributes {
  std::map<std::string, std::string> values;
  std::set<std::string> nulls;
};

// nullopt when there is nothing to store. Throws nlohmann::json::exception on invalid UTF-8.
std::optional<std::string> EncodeAttributes(const std::map<std::string, std::string>& values,
                                            const std::set<std::string>& nulls);

// Throws std::invalid_argument unless `text` is a JSON object of strings and nulls.
TreeAttributes DecodeAttributes(const std::string& text);

}  // namespace forestmap::storage::internal
