#include "server/grpc/map_set.h"

#include <fnmatch.h>

#include <algorithm>

#include "server/app/errors.h"
#include "server/grpc/convert.h"
#include "server/grpc/validation.h"

namespace forestmap::server {

std::vector<storage::MapInfo> ResolveMapSet(storage::MapStore& store, const Caller& caller,
                                            std::string_view rpc, const v1::MapSet& set,
                                            const algorithms::RelocalizeQuery& query,
                                            const algorithms::RelocalizerOptions& options,
                                            int max_maps, int max_searches) {
  std::vector<storage::MapInfo> maps;
  if (set.names_size() > 0) {
    for (const std::string& name : set.names()) {
      Require(caller, rpc, name);
      maps.push_back(store.GetMap(name));
    }
  } else {
    for (storage::MapInfo& info : store.ListMaps()) {
      const bool named =
          set.all_readable() || fnmatch(set.name_pattern().c_str(), info.name.c_str(), 0) == 0;
      if (named && caller.CanRead(info.name)) maps.push_back(std::move(info));
    }
    if (maps.empty()) {
      const std::string who = caller.token ? caller.Name() + " may read" : "the server holds";
      throw ServiceError(ErrorCode::kNotFound, set.all_readable()
                                                   ? "maps: there is no map " + who
                                                   : "maps.name_pattern: no map " + who +
                                                         " matches " + Quoted(set.name_pattern()));
    }
    std::sort(maps.begin(), maps.end(),
              [](const auto& a, const auto& b) { return a.name < b.name; });
  }
  std::vector<storage::MapInfo> candidates = CandidateMaps(maps, query, options);
  if (candidates.size() > static_cast<size_t>(max_maps)) {
    throw LimitError("maps: " + std::to_string(candidates.size()) +
                     " maps with trees may hold the sensor, over the limit of " +
                     std::to_string(max_maps) +
                     " per question; name fewer maps, or give a prior to leave out the far ones");
  }
  const size_t searches = SearchCount(candidates);
  if (searches > static_cast<size_t>(max_searches)) {
    throw LimitError("maps: the maps that may hold the sensor need " + std::to_string(searches) +
                     " searches (one per CRS, one per map without a CRS), over the limit of " +
                     std::to_string(max_searches) +
                     " per question; give the maps a common CRS, name fewer maps, or give a prior");
  }
  return candidates;
}

v1::RelocalizeResponse ToProto(const MapSetAnswer& answer) {
  v1::RelocalizeResponse response = ToProto(answer.result);
  if (answer.rival) response.set_rival_map_name(answer.answers[*answer.rival].map);
  if (answer.reported) {
    const MapAnswer& reported = answer.answers[*answer.reported];
    response.set_map_name(reported.map);
    response.set_map_version(reported.entry.version);
    for (size_t i = 0; i < reported.match_maps.size(); ++i) {
      if (reported.match_maps[i] != reported.map) {
        response.mutable_matches(static_cast<int>(i))->set_map_name(reported.match_maps[i]);
      }
    }
  }
  return response;
}

}  // namespace forestmap::server
