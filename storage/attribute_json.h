#pragma once
// A tree's survey columns as stored by both stores: one JSON object, a string per known value and
// null per unknown one ({"Spp": "41", "LI": null}), or SQL NULL when the tree has neither.

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

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

// The order of a map's attribute columns (MapSnapshot::attribute_columns) as stored: a JSON array
// of the names, "" for none.
std::string EncodeColumnOrder(const std::vector<std::string>& names);
// kInternal naming the map when the stored text is not an array of strings.
std::vector<std::string> DecodeColumnOrder(const std::string& map_name, const std::string& text);
// The order after an upload whose file had the attribute columns `uploaded`, in its order: those
// of `stored` first (an append keeps the map's order), then the new ones; `replace`: `uploaded`
// alone. Empty `uploaded` (the order unknown): `stored`.
std::vector<std::string> MergeColumnOrder(const std::vector<std::string>& stored,
                                          const std::vector<std::string>& uploaded, bool replace);

}  // namespace forestmap::storage::internal
